"""A preset's contacts (steps of taimill.model.preset.load_preset): its pair and the
friction of each contact kind, tuned by [friction] and [friction_KIND], and the normal
laws of its contact set, or of `law` derived for its balls and jar, softened."""

from __future__ import annotations

from pathlib import Path

from taimill.model import rules
from taimill.model.contact.registry import NAMES as LAW_NAMES
from taimill.model.contact_sets import NormalLaw, contact_laws, soften
from taimill.model.jars import Jar
from taimill.model.materials import (FRICTION_KEYS, Balls, Friction, contact_table, load_friction, pair_estimates,
                                     read_friction)
from taimill.model.tables import Table

# Contact kinds a preset may give its own friction pair and tuning (a coated jar: ball-wall only).
KINDS = ("ball_ball", "ball_wall")


def frictions(t: Table, folder: Path, warnings: list) -> tuple:
    """(pair: a name or a pair file's resolved path, the ball-ball friction, the ball-wall
    one or None where it is the same, the pair's contact set or None, whether [friction]
    tuned the pair). folder: the preset's; the pair's estimates join `warnings`."""
    pair = t.get("pair", kind=str)
    pair_base = Path.cwd() if t.where("pair") == "command line" else folder
    friction, contact = load_friction(pair, t.where("pair"), base=pair_base)
    warnings += pair_estimates(pair)
    if pair.endswith(".toml"):  # a pair file: its resolved path, valid from any directory
        pair = str((pair_base / pair).resolve())
    ft = t.table("friction", required=False, known=FRICTION_KEYS)
    if ft is not None:  # the pair's friction, tuned by the user
        friction = read_friction(ft, f"{pair} (tuned)", friction)
        ft.done()
    both = [_kind_friction(t, kind, friction, contact, pair_base, warnings) for kind in KINDS]
    return pair, both[0], (both[1] if both[1] != both[0] else None), contact, ft is not None


def normal_laws(t: Table, pair: str, contact: str | None, friction: Friction, tuned: bool, balls: Balls, jar: Jar,
                warnings: list) -> tuple[NormalLaw, NormalLaw, float]:
    """(ball-ball law, ball-wall law, softening) of the contact set of `pair`, or of
    `law`; an untuned pair used for other materials than its own is said in `warnings`."""
    law = t.get("law", None, allowed=LAW_NAMES)
    ball_ball, ball_wall = contact_laws(contact, law, balls, jar, t.source, notes=warnings)
    if not tuned:
        warnings += _borrowed_friction(pair, contact, friction, balls, jar)
    softening = t.get("softening", 1.0, lo=1.0, hi=rules.SOFTENING_MAX)
    if softening != 1.0:
        ball_ball, ball_wall = soften(ball_ball, softening), soften(ball_wall, softening)
        warnings.append(rules.softening_note(softening))
    return ball_ball, ball_wall, softening


def size_note(contact: str | None, balls: Balls, jar: Jar) -> str | None:
    """rules.ball_size_note against the ball size the contact set in use was measured
    for (a set derived for these balls: none)."""
    measured = None
    if contact is not None:
        table = contact_table(contact)[0]
        if rules.measured_set_applies(table.get("ball"), table.get("wall"), balls, jar):
            measured = table.get("ball_radius_mm")
    return rules.ball_size_note(balls.radius, measured * 1e-3 if isinstance(measured, (int, float)) else None, contact)


def _borrowed_friction(pair: str, contact: str | None, friction: Friction, balls: Balls, jar: Jar) -> list[str]:
    """The warning line when a pair's friction, measured with its contact set's ball and
    wall materials, is used for other materials (its normal laws are then derived:
    contact_sets.contact_source): friction describes the surfaces with their powder, and
    no material's data gives it."""
    if contact is None:  # a pair without a measured set (dry-ceramic-powder) says what it assumes itself
        return []
    table, _, _ = contact_table(contact)
    measured = (table.get("ball"), table.get("wall"))
    if rules.measured_set_applies(*measured, balls, jar):
        return []
    return [f"friction of pair {Path(pair).stem} (mu_s = {friction.mu_s:g}, mu_d = {friction.mu_d:g}) was measured for "
            f"{measured[0]} balls on {measured[1]} walls and is used as it is for {balls.material.name} balls on "
            f"{jar.wall_material} walls; --pair names one for your powder (taimill materials lists them, e.g. "
            "dry-ceramic-powder)"]


def _kind_friction(t: Table, kind: str, friction: Friction, contact: str | None, pair_base: Path,
                   warnings: list) -> Friction:
    """Friction of one contact kind: `pair_KIND` (a pair of the same contact set)
    instead of `pair`, then tuned by `[friction_KIND]`; else the preset's friction."""
    key = f"pair_{kind}"
    if t.has(key):
        name = t.get(key, kind=str)
        base = Path.cwd() if t.where(key) == "command line" else pair_base
        friction, own = load_friction(name, t.where(key), key, base)
        warnings += pair_estimates(name)
        rules.same_contact_set(t.where(key), key, name, own, contact, "`pair` uses",
                               " (the normal laws come from `pair`; pick a pair of the same contact set)")
    ft = t.table(f"friction_{kind}", required=False, known=FRICTION_KEYS)
    if ft is not None:
        friction = read_friction(ft, f"{friction.name} ({kind.replace('_', '-')}, tuned)", friction)
        ft.done()
    return friction
