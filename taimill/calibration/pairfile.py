"""Pair files: a friction pair and its contact set in one small TOML file, with the
keys and units of taimill/data/materials.toml, so a preset can say
`pair = "my-fit.toml"` (relative to the preset file) instead of a built-in name:

    [pair.NAME]                 # friction, thesis eq 3.7
    contact = "NAME"
    mu_s = 0.8
    mu_d = 0.67
    v_s_mm_s = 1
    v_d_mm_s = 10

    [contact.NAME]              # normal law, thesis Tables 3.2 / 5.2
    ball = "zirconia"           # built-in materials
    wall = "zirconia"
    law = "adams-impact"
    ball_radius_mm = 3
    ball_ball = { c_max_Ns_per_mm = 0.33, d_mm = 0.105, e = 0.9, u_ref_mm_s = 3300 }
    ball_wall = { c_max_Ns_per_mm = 0.57, d_mm = 0.105, e = 0.9, u_ref_mm_s = 3300 }

materials.load_friction reads it; the contact table may also name a built-in set."""

from __future__ import annotations

import json
from pathlib import Path

from taimill.model.materials import contact_table, load_friction
from taimill.store.output import whole_file


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)  # shortest round-tripping form, valid TOML
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + " }"
    return json.dumps(str(v), ensure_ascii=False)  # a TOML basic string


HEADER = "# Pair file written by `taimill calibrate fit`"  #: the start of every pair file's first line (its mark)


def is_fitted_pair_file(path) -> bool:
    """True if `path` is a pair file `calibrate fit` wrote (its first line), the only
    kind `calibrate fit --out --overwrite` replaces."""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return f.readline().startswith(HEADER)
    except OSError:
        return False


def write_pair_file(path, pair: str, *, law: str, override: dict, name: str | None = None,
                    comments: list[str] = ()) -> Path:
    """Write `pair`'s friction and contact set, with `override` (contact-table entries,
    as for contact_sets.pair_contact) and normal law `law`, as a pair file named NAME
    (default "<pair>-fit"). `comments` go on top (what was fitted, to which data),
    after the HEADER line that marks the file as one taimill wrote."""
    path = Path(path)
    friction, contact_id = load_friction(pair, "command line", base=Path.cwd())
    table, _, _ = contact_table(contact_id)
    name = name or f"{Path(pair).stem if pair.endswith('.toml') else pair}-fit"
    contact = {**table, "law": law, **{k: {**table[k], **v} for k, v in override.items()}}
    lines = [f"{HEADER} ({law})."] + [f"# {c}" for c in comments] + [
        "", f"[pair.{json.dumps(name)}]", f"contact = {json.dumps(name)}",
        f"mu_s = {_value(friction.mu_s)}", f"mu_d = {_value(friction.mu_d)}",
        f"v_s_mm_s = {_value(round(friction.v_s * 1e3, 12))}", f"v_d_mm_s = {_value(round(friction.v_d * 1e3, 12))}",
        "", f"[contact.{json.dumps(name)}]", *(f"{k} = {_value(v)}" for k, v in contact.items()),
    ]
    with whole_file(path, "pair file") as part:  # whole or not at all: a full disk leaves nothing behind
        part.write_text("\n".join(lines) + "\n")
    return path
