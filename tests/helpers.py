"""Hand-built mills for validation tests (one or two balls, no drive, chosen laws), and
the small, full or read-only disks of the fault tests (`tmpfs`)."""

from __future__ import annotations

import contextlib
import os
import subprocess
from pathlib import Path

import pytest

from taimill.model.contact_sets import NormalLaw, pair_contact
from taimill.model import laws as laws_np
from taimill.calibration import runs as calibration
from taimill.calibration.runs import run_spec, two_sphere_spec

FRICTIONLESS = calibration.FRICTIONLESS


def steel(law=None):
    """(ball, jar, ball-ball law, ball-wall law, friction) of the thesis' steel set."""
    return pair_contact("steel-steel", law=law)


def elastic(law: NormalLaw) -> NormalLaw:
    """The same law without damping (pure Hertz)."""
    return NormalLaw("adams-impact", law.k, 1.5, 0.0, law.d, law.m_eff, 1.0, law.u_ref)


def dt_for(law: NormalLaw, v: float, steps_per_contact: int) -> float:
    t_c = laws_np.simulate_impact(law.model, law.k, law.c, law.d, law.m_eff, v)["duration"][0]
    return float(t_c / steps_per_contact)


def two_ball_impact(bb: NormalLaw, friction, v_rel, offset, *, dt):
    """Two 6 mm steel balls: ball 0 at rest, ball 1 approaching along -x at v_rel (m/s)
    with its centre `offset` (m) off the line in y; no gravity. Returns (final state,
    events). The geometry is `taimill.calibration.runs.two_sphere_spec`."""
    ball, jar, _, bw, _ = steel()
    return run_spec(two_sphere_spec(ball, jar, bb, bw, friction, v_rel, offset, dt=dt))


def numbers_without_unit(summary: dict) -> list[str]:
    """Paths of the numbers in a JSON summary that its `units` table does not cover: a
    number is covered by its own key or by the name of an object enclosing it."""
    units, missing = summary["units"], []

    def walk(v, path, key, covered):
        if isinstance(v, dict):
            for k, x in v.items():
                walk(x, f"{path}.{k}", k, covered or (k in units and isinstance(x, dict)))
        elif isinstance(v, (list, tuple)):
            for i, x in enumerate(v):
                walk(x, f"{path}[{i}]", key, covered)
        elif isinstance(v, (int, float)) and not isinstance(v, bool) and not covered and key not in units:
            missing.append(path.lstrip("."))

    walk({k: v for k, v in summary.items() if k != "units"}, "", None, False)
    return missing


@contextlib.contextmanager
def tmpfs(folder, *options, free_bytes: int | None = None):
    """A tmpfs mounted at `folder` (created) with mount `options` ("size=2m", "ro"): a
    small or full disk (`free_bytes`: filled but for about that many bytes) or a read-only
    folder (the tests run as root, who ignores chmod). Skips the test where mounting is
    not allowed; unmounted on the way out."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", ",".join(options) or "defaults", "tmpfs", str(folder)],
                         capture_output=True, text=True, check=False)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({res.stderr.strip() or res.returncode})")
    try:
        if free_bytes is not None:
            stat = os.statvfs(folder)
            with open(folder / "filler", "wb") as f:
                try:
                    f.write(b"\0" * max(0, stat.f_bavail * stat.f_frsize - free_bytes))
                except OSError:
                    pass
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)
