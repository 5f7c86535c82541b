"""How taimill's contact models are expressed in LIGGGHTS-PUBLIC 3.8 (docs/liggghts.md):
the normal law as `model hertz` or `hooke/stiffness` with the restitution or stiffness
that gives taimill's damping, and each contact kind's tangential and rolling sub-models
from the tables below (keyed by the sub-models' registry names); what has no exact
counterpart is a warning, or refused with `strict`."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from taimill.errors import ConfigError
from taimill.model import laws as laws_np
from taimill.model.contact import rolling, rolling_epsd2, tangential, tangential_history
from taimill.model.contact.damping import damping_ratio
from taimill.model.contact.registry import law_by_name
from taimill.model.preset import Preset


@dataclass
class Mapping:
    """How taimill's contact model is expressed in LIGGGHTS, with what could not be."""

    normal: str  #: LIGGGHTS normal model (`hertz` or `hooke/stiffness`)
    tangential: str  #: LIGGGHTS tangential model of ball-ball contacts (tangential_models has both kinds)
    #: "ball_ball"/"ball_wall" -> LIGGGHTS tangential model
    tangential_models: dict = field(default_factory=dict)
    #: "ball_ball"/"ball_wall" -> the LIGGGHTS settings its tangential model needs (e.g. ["tangential_damping off"])
    tangential_settings: dict = field(default_factory=dict)
    #: "ball_ball"/"ball_wall" -> LIGGGHTS rolling_friction model (cdt, epsd2); absent: no rolling resistance
    rolling_models: dict = field(default_factory=dict)
    restitution: dict = field(default_factory=dict)  #: "ball_ball"/"ball_wall" -> LIGGGHTS input e
    stiffness: dict = field(default_factory=dict)  #: hooke/stiffness only: kn, gamman per contact type
    friction: dict = field(default_factory=dict)  #: "ball_ball"/"ball_wall" -> LIGGGHTS coefficientFriction
    rolling: dict = field(default_factory=dict)  #: "ball_ball"/"ball_wall" -> coefficientRollingFriction; {}: off
    notes: list = field(default_factory=list)  #: exact correspondences, one line each
    warnings: list = field(default_factory=list)  #: approximations, one line each


def _liggghts_restitution(c_tsuji: float) -> float:
    """LIGGGHTS' `hertz` damping is γ_n = 2√(5/6) β √(S_n m*), β = −ln e/√(ln² e + π²):
    taimill's hertz-mindlin with c = 2√(5/6) β. The e LIGGGHTS must be given for a
    damping c (it differs from the restitution the clamped law then gives)."""
    beta = c_tsuji / (2.0 * math.sqrt(5.0 / 6.0))
    if not 0.0 < beta < 1.0:
        raise ValueError(f"damping {c_tsuji} has no restitution form")
    return math.exp(-math.pi * beta / math.sqrt(1.0 - beta * beta))


@functools.lru_cache(maxsize=64)
def _hertz_input_e(e_target: float) -> float:
    """LIGGGHTS input e for which its clamped Hertz contact (limitForce on) rebounds
    with e_target. The clamped Tsuji law is scale-free, so this is one function of e:
    bisection on simulated unit impacts (k = m = u = 1) over the input e."""
    mindlin = law_by_name("hertz-mindlin")
    lo, hi = (0.05 if e_target > 0.22 else 1e-3), 0.999  # input 0.05 gives 0.21 (near e = 0 impacts end slowly)
    for _ in range(5):
        grid = np.linspace(lo, hi, 17)
        c = [2.0 * math.sqrt(5.0 / 6.0) * damping_ratio(e) for e in grid]
        got = laws_np.simulate_impact(mindlin, 1.0, c, 1.0, 1.0, 1.0, steps=600)["e"]
        i = int(np.argmax(got >= e_target)) if (got >= e_target).any() else len(grid) - 1
        lo, hi = grid[max(i - 1, 0)], grid[i]
    return float(0.5 * (lo + hi))


def _restitution_at(law, speeds) -> np.ndarray:
    """Restitution of a taimill contact at impact speeds (m/s), F ≥ 0 clamp included."""
    return laws_np.simulate_impact(law.model, law.k, law.c, law.d, law.m_eff, np.asarray(speeds))["e"]


def contact_mapping(preset: Preset, *, strict: bool = False) -> Mapping:
    """The LIGGGHTS contact models of a preset; ConfigError for what has no equivalent
    (with `strict`, also for what would only be approximated)."""
    bb, bw = preset.ball_ball, preset.ball_wall
    law = bb.law
    mu_r, rolling_models, r_notes, r_warnings = _rolling(preset, strict)  # its refusals first, as before
    mu, models, settings, notes, warnings = _tangential(preset, strict)
    m = Mapping(normal="hertz", tangential=models["ball_ball"], tangential_models=models,
                tangential_settings=settings, friction=mu, rolling=mu_r, rolling_models=rolling_models,
                notes=notes + r_notes, warnings=warnings + r_warnings)
    if law == "hertz-mindlin":
        for name, c in (("ball_ball", bb), ("ball_wall", bw)):
            m.restitution[name] = _liggghts_restitution(c.c)
        m.notes.append(
            "normal: hertz-mindlin = LIGGGHTS `model hertz` with limitForce on (same k = 4/3 E* √R*, same "
            "damping 2√(5/6) β √(S_n m*)); LIGGGHTS' input e is the one whose β gives taimill's calibrated "
            f"damping: ball-ball {m.restitution['ball_ball']:.4f}, ball-wall {m.restitution['ball_wall']:.4f} "
            f"(both rebound with e = {bb.e:g} once the force is clamped at 0)")
    elif law == "kelvin-voigt":
        m.normal = "hooke/stiffness"
        m.stiffness = {"ball_ball": (bb.k, bb.c), "ball_wall": (bw.k, bw.c)}
        m.notes.append(
            "normal: kelvin-voigt = LIGGGHTS `model hooke/stiffness` with absolute_damping on and limitForce on "
            f"(kn = {bb.k:.4g} / {bw.k:.4g} N/m, gamman = {bb.c:.4g} / {bw.c:.4g} N·s/m ball-ball / ball-wall); "
            "its tangential spring kt = 2/7 kn, tangential damping off")
        mindlin = [(k, f.tangential) for k, f in zip(("ball_ball", "ball_wall"), preset.frictions)
                   if TANGENTIAL_EXPORT[f.tangential].mindlin]
        if mindlin:  # LIGGGHTS' hooke/stiffness spring is the constant kt above, taimill's Mindlin's
            kind, name = mindlin[0]
            text = (f"tangential = {name} with kelvin-voigt: taimill's tangential spring is Mindlin's "
                    "k_t = 8 G* √(R* u) whatever the normal law, LIGGGHTS' `hooke/stiffness` one is the constant kt "
                    "= 2/7 kn; the same cap μ_d |F_n|")
            if strict:
                raise ConfigError(preset.source, _key(preset, kind, "tangential"), name,
                                  text + "; use law = \"hertz-mindlin\", or export without --strict to map it")
            m.warnings.append(text)
    else:
        speeds = np.array([0.5, 2.0, 6.0])
        e_bb = _restitution_at(bb, [bb.u_ref])[0]
        e_bw = _restitution_at(bw, [bw.u_ref])[0]
        spread = _restitution_at(bw, speeds)
        text = (f"{law} has no LIGGGHTS equivalent (its restitution depends on the impact speed: ball-wall e = "
                + ", ".join(f"{e:.3f}" for e in spread) + " at " + ", ".join(f"{v:g}" for v in speeds) + " m/s)")
        if strict:
            raise ConfigError(preset.source, "law", law,
                              f"{text}; use law = \"hertz-mindlin\" (constant restitution), or export without "
                              "--strict to map it")
        m.restitution = {"ball_ball": _hertz_input_e(round(float(e_bb), 4)), "ball_wall": _hertz_input_e(round(float(e_bw), 4))}
        m.warnings.append(
            f"normal: {text}; mapped to LIGGGHTS `model hertz` (same Hertz stiffness) with the constant "
            f"restitution it has at u_ref = {bb.u_ref:g} m/s: ball-ball {e_bb:.3f}, ball-wall {e_bw:.3f}")
    return m


# Each taimill tangential / rolling sub-model (by its registry name) and how the export
# writes it: LIGGGHTS' pair_style sets the models of ball-ball contacts and the wall fix
# its own, so each contact kind is written with its own sub-models (the installed 3.8
# accepts different ones in the two commands).


@dataclass(frozen=True)
class TangentialExport:
    """How one tangential sub-model is written for LIGGGHTS."""

    keyword: str  #: LIGGGHTS `tangential` model
    settings: tuple  #: settings it needs after the model (none: LIGGGHTS' defaults)
    stiction: bool  #: reads μ_s, which one Coulomb coefficient cannot express when μ_s > μ_d
    note: str  #: the mapping line; {mu} is μ_d (-), {v_s} v_s (mm/s)
    mindlin: bool = False  #: taimill's spring is Mindlin's k_t: exact only under LIGGGHTS' `model hertz`


@dataclass(frozen=True)
class RollingExport:
    """How one rolling sub-model is written for LIGGGHTS: `exact` (a note), `approximate`
    (a warning; refused with --strict) or `refused` per contact kind."""

    keyword: str  #: LIGGGHTS `rolling_friction` model
    ball_ball: str  #: exact | approximate
    ball_wall: str  #: approximate | refused
    text: dict  #: kind -> the mapping line (or the refusal); {mu_r} is μ_r (-)


TANGENTIAL_EXPORT = {
    tangential.REGULARISED_COULOMB.name: TangentialExport(
        "history", (), True,
        "Coulomb μ = {mu:g} (LIGGGHTS `tangential history`: a tangential spring capped at μ F_n; taimill's "
        "regularisation below v_s = {v_s:g} mm/s has no counterpart, the sliding force is the same)"),
    tangential_history.HISTORY.name: TangentialExport(
        "history", ("tangential_damping off",), False,
        "tangential = history, μ_d = {mu:g}: LIGGGHTS `tangential history` with `tangential_damping off` and "
        "coefficientFriction μ_d, exact (the same spring k_t = 8 G* √(R* δ) on the same projected history, capped "
        "at μ_d |F_n|; μ_s, v_s and v_d are not read by this model)", mindlin=True),
}
ROLLING_EXPORT = {
    rolling.CONSTANT_TORQUE.name: RollingExport("cdt", "approximate", "refused", {
        "ball_ball": "μ_r = {mu_r:g} as LIGGGHTS `rolling_friction cdt` (the same torque μ_r R* F_n against "
                     "ω_i − ω_j), except that LIGGGHTS takes F_n without its damping part and has no cap: near "
                     "ω_r = 0 its torque flips sign every step where taimill's settles the rolling",
        "ball_wall": "ball-wall rolling resistance has no LIGGGHTS equivalent in a turning jar (its wall contacts "
                     "brake the ball's ground-frame spin, taimill's the spin relative to the wall); set it to 0 to "
                     "export, or use rolling = \"epsd2\""}),
    rolling_epsd2.EPSD2.name: RollingExport("epsd2", "exact", "approximate", {
        "ball_ball": "rolling = epsd2, μ_r = {mu_r:g}: LIGGGHTS `rolling_friction epsd2` with "
                     "coefficientRollingFriction μ_r, exact (the same spring k_r = k_t R*² on ω_i − ω_j "
                     "projected on the tangent plane, capped at μ_r R* |F_n|, no dashpot)",
        "ball_wall": "rolling = epsd2, μ_r = {mu_r:g}: LIGGGHTS `rolling_friction epsd2` on the wall fix, the same "
                     "spring and cap, except the spin it loads: LIGGGHTS' wall contacts take the ball's ground-frame "
                     "spin (a mesh has no spin of its own), taimill's the spin relative to the jar wall, which turns "
                     "with the jar; a ball carried round by the wall at the jar's spin loads LIGGGHTS' spring until it "
                     "slips at μ_r R |F_n| and taimill's not at all"}),
}


def _key(preset: Preset, kind: str, name: str) -> str:
    """The preset key a refusal names: friction.NAME, or friction_KIND.NAME when the
    contact kinds have their own friction."""
    return f"friction.{name}" if preset.wall_friction is None else f"friction_{kind}.{name}"


def _export_of(table: dict, preset: Preset, kind: str, key: str, name: str):
    """The row of sub-model `name` in an export table (TANGENTIAL_EXPORT, ROLLING_EXPORT;
    key: its preset key, "tangential" or "rolling"). A registered sub-model without a row
    is refused in one line: a sub-model is registered for runs before it has an export."""
    if name not in table:
        raise ConfigError(preset.source, _key(preset, kind, key), name,
                          f"has no LIGGGHTS export; the export writes {key} = {', '.join(table)}")
    return table[name]


def _tangential(preset: Preset, strict: bool) -> tuple[dict, dict, dict, list, list]:
    """(μ, LIGGGHTS model, its settings; each per kind, notes, warnings) of the
    tangential sub-models (TANGENTIAL_EXPORT):
    LIGGGHTS' `coefficientFriction` is a per-type-pair property and the wall is its own
    atom type, so a coated jar (`pair_ball_wall`) maps exactly. Stiction μ_s > μ_d of
    the regularised Coulomb model has no counterpart: μ = μ_d with a warning, or
    refused with `strict`."""
    mu, models, settings, notes, warnings = {}, {}, {}, [], []
    fbb, fbw = preset.frictions
    same = (fbb.tangential, fbb.mu_s, fbb.mu_d) == (fbw.tangential, fbw.mu_s, fbw.mu_d)
    for kind, f in zip(("ball_ball", "ball_wall"), preset.frictions):
        t = _export_of(TANGENTIAL_EXPORT, preset, kind, "tangential", f.tangential)
        mu[kind], models[kind], settings[kind] = f.mu_d, t.keyword, list(t.settings)
        where = "" if same else f" ({kind.replace('_', '-')})"
        stiction = t.stiction and f.mu_s != f.mu_d
        if stiction and strict:
            key = "pair" if preset.wall_friction is None else f"pair_{kind}"
            raise ConfigError(preset.source, key, f.name,
                              f"stiction μ_s = {f.mu_s:g} > μ_d = {f.mu_d:g} ({kind.replace('_', '-')}) has no "
                              "LIGGGHTS equivalent (set mu_s = mu_d or tangential = \"history\", or export without "
                              "--strict to map μ = μ_d)")
        if same and kind == "ball_wall":
            continue  # one line for both kinds
        if stiction:
            warnings.append(f"friction{where}: stiction μ_s = {f.mu_s:g} (below v_d = {f.v_d * 1e3:g} mm/s) has no "
                            f"LIGGGHTS equivalent; mapped to one Coulomb coefficient μ = μ_d = {f.mu_d:g} "
                            "(`tangential history`)")
        else:
            notes.append(f"friction{where}: " + t.note.format(mu=f.mu_d, v_s=f.v_s * 1e3))
    return mu, models, settings, notes, warnings


def _rolling(preset: Preset, strict: bool) -> tuple[dict, dict, list, list]:
    """(μ_r per kind, LIGGGHTS rolling model per kind, notes, warnings) of the rolling
    sub-models (ROLLING_EXPORT); μ_r = {} and no model when neither kind has rolling
    resistance. A kind with μ_r = 0 has no rolling_friction in its command."""
    mu_r, models, notes, warnings = {}, {}, [], []
    for kind, f in zip(("ball_ball", "ball_wall"), preset.frictions):
        if f.mu_r == 0:
            continue
        r = _export_of(ROLLING_EXPORT, preset, kind, "rolling", f.rolling)
        how = getattr(r, kind)
        text = r.text[kind].format(mu_r=f.mu_r)
        if how == "refused" or (how == "approximate" and strict):
            raise ConfigError(preset.source, _key(preset, kind, "mu_r"), f.mu_r,
                              text + ("" if how == "refused" else "; export without --strict to map it"))
        (notes if how == "exact" else warnings).append(f"rolling resistance ({kind.replace('_', '-')}): {text}")
        mu_r[kind], models[kind] = f.mu_r, r.keyword
    if not models:
        notes.append("rolling resistance: none in either code")
        return {}, {}, notes, warnings
    return {"ball_ball": 0.0, "ball_wall": 0.0, **mu_r}, models, notes, warnings
