"""Given start positions of the balls (a preset's `initial_positions`): read from CSV
or NPZ and checked to lie inside the jar without overlaps."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

from taimill.errors import ConfigError
from taimill.model import files, geometry
from taimill.model.jars import Jar
from taimill.model.materials import Balls
from taimill.model.overlap import first_overlap


def load_positions(name: str, base: Path, balls: Balls, jar: Jar, source) -> np.ndarray:
    """Ball centres (N, 3), m, jar frame, from CSV (x,y,z per line) or NPZ (array 'positions')."""
    files.check_path_text(name, source, "initial_positions")
    p = Path(name) if Path(name).is_absolute() else base / name
    npz = p.suffix == ".npz"
    data = files.read_bytes(p, source, "initial_positions") if npz else files.read_text(p, source, "initial_positions", "CSV file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty file: loadtxt warns, the shape check below reports it
            if npz:
                x = np.load(io.BytesIO(data), allow_pickle=False)["positions"]
            else:
                x = np.loadtxt(io.StringIO(data), delimiter=",", ndmin=2)
            x = np.asarray(x, dtype=float)
    except (OSError, KeyError, ValueError, TypeError, EOFError) as err:
        raise ConfigError(source, "initial_positions", name, f"cannot read ({err})") from None
    if x.shape != (balls.count, 3):
        raise ConfigError(source, "initial_positions", name, f"shape {x.shape}; need ({balls.count}, 3) ball centres in m")
    if not np.isfinite(x).all():
        raise ConfigError(source, "initial_positions", name, "every coordinate must be a finite number (m)")
    r = balls.radius
    phi, _ = geometry.profile_sdf(jar.profile, x[:, :2])
    if (phi < r).any() or (x[:, 2] < r).any() or (x[:, 2] > jar.height - r).any():
        raise ConfigError(source, "initial_positions", name, "a ball is not fully inside the jar")
    pair = first_overlap(x, r)
    if pair is not None:
        i, j = pair
        raise ConfigError(source, "initial_positions", name, f"balls {i} and {j} overlap (rows {i + 1} and {j + 1})")
    return x
