"""Planetary mills as data: the sun wheel (plate) and its effective radius R_p, the gear
that ties the bowls' spin to it, the plate speeds the maker allows, the stations and
the maker's bowls, read from taimill/data/mills/NAME.toml or a user's mill file, every
number with its source or marked as an estimate (docs/mills.md).

Gear convention: makers write the gear as "1:−2" (sun wheel : bowl), the bowl's speed
*relative to the sun wheel* per turn of the sun wheel, r = ω/Ω (Fritsch names it the
relative transmission ratio, i_relative; docs/mills.md says what was found for each
maker). taimill's speed ratio is the bowl's absolute spin over Ω, K = ω/Ω + 1
(taimill.model.drive), so K = r + 1: 1:−2 is K = −1 (`k_from_maker`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from taimill.errors import ConfigError
from taimill.model import files
from taimill.model.provenance import Origin, read_origins
from taimill.model.ranges import RANGES, Range
from taimill.model.tables import Table, read_toml

DEFAULT = "fritsch-p4"  #: the thesis' mill, the mill of every preset that names none
GEARS = ("fixed", "set", "free")
NUMBERS = ("plate_radius_mm", "gear_ratio", "gear_ratios", "ratio_min", "ratio_max",
           "plate_rpm_min", "plate_rpm_max", "stations", "bowls_ml")
MILL_KEYS = ("maker", "model", "description", "gear", *NUMBERS, "sources", "estimates")
TOLERANCE = 1e-9  #: a K given for a mill with a set of gears matches one within this


def k_from_maker(r: float) -> float:
    """K = ω/Ω + 1 of a maker's gear "1:r" (r = ω/Ω, the bowl's speed relative to the
    sun wheel over the sun wheel's): 1:−2 → K = −1."""
    return r + 1.0


def maker_from_k(k: float) -> float:
    """The maker's r of "1:r" for a speed ratio K: r = K − 1."""
    return k - 1.0


def maker_text(r: float) -> str:
    """A gear as makers write it, "1:-2"."""
    return f"1:{r:g}"


@dataclass(frozen=True)
class Gear:
    """How a mill ties the bowls' spin to the plate's: one fixed ratio, a set to choose
    from, or free (separate motors) within a K range or with none known."""

    kind: str  #: "fixed", "set" or "free"
    ratios: tuple[float, ...] = ()  #: maker's r of "1:r" (fixed: one; set: several)
    k_min: float | None = None  #: free gear: lowest K the mill drives; None: unknown
    k_max: float | None = None

    @property
    def ks(self) -> tuple[float, ...]:
        """The speed ratios K of a fixed gear or set."""
        return tuple(k_from_maker(r) for r in self.ratios)

    @property
    def text(self) -> str:
        """As the maker writes it: "1:-2", "1:-2.5 or 1:-3", "free"."""
        if self.kind == "free":
            return "free"
        return " or ".join(maker_text(r) for r in self.ratios)

    @property
    def k_text(self) -> str:
        """The same as K: "K = -1", "K = -1.5 or -2", "K free", "K in [-4, 0]"."""
        if self.kind != "free":
            return "K = " + " or ".join(f"{k:g}" for k in self.ks)
        if self.k_min is None and self.k_max is None:
            return "K free"
        lo = "-inf" if self.k_min is None else f"{self.k_min:g}"
        hi = "inf" if self.k_max is None else f"{self.k_max:g}"
        return f"K in [{lo}, {hi}]"

    def as_dict(self) -> dict:
        return {"kind": self.kind, "maker": self.text, "ratios_maker": list(self.ratios), "ratios_k": list(self.ks),
                "k_min": self.k_min, "k_max": self.k_max}


@dataclass(frozen=True)
class Mill:
    """A planetary mill. Numbers in SI but the speeds (rpm) and bowl volumes (ml), as
    makers quote them; `origins` holds every number's source or estimate note."""

    name: str
    source: str
    maker: str
    model: str
    description: str
    plate_radius: float  #: m, R_p: plate axis to bowl axis
    gear: Gear
    plate_rpm_min: float | None  #: lowest plate speed, rpm (of |Ω|); None: unknown
    plate_rpm_max: float | None  #: highest plate speed, rpm (of |Ω|); None: unknown
    stations: int  #: bowls the plate carries
    bowls_ml: tuple[int, ...]  #: the maker's bowl volumes that fit, ml
    origins: tuple[Origin, ...] = ()

    def origin(self, key: str) -> Origin | None:
        return next((o for o in self.origins if o.key == key), None)

    def is_estimate(self, key: str) -> bool:
        o = self.origin(key)
        return o is not None and o.estimate

    @property
    def plate_range(self) -> Range:
        """Allowed plate speeds Ω (rpm): the maker's where known (a negative Ω is the
        mirror image of a positive one), else the global sanity cap RANGES["plate_rpm"]."""
        if self.plate_rpm_max is None:
            return RANGES["plate_rpm"]
        hi = self.plate_rpm_max
        return Range(-hi, hi, "rpm", live=(0.0, hi))

    def estimates_in_use(self, radius_from_mill: bool = True) -> list[str]:
        """One warning line naming the estimated numbers a run on this mill uses: R_p
        (unless the preset gives its own), a fixed gear or set of gears, the plate speed
        limits; none if they are all sourced."""
        g = self.gear
        shown = {"plate_radius_mm": f"R_p = {self.plate_radius * 1e3:g} mm", "gear_ratio": f"gear {g.text} ({g.k_text})",
                 "gear_ratios": f"gears {g.text} ({g.k_text})", "plate_rpm_min": f"lowest plate speed {self.plate_rpm_min or 0:g} rpm",
                 "plate_rpm_max": f"highest plate speed {self.plate_rpm_max or 0:g} rpm"}
        used = [k for k in shown if k != "plate_radius_mm" or radius_from_mill]
        estimated = [shown[k] for k in used if self.is_estimate(k)]
        if not estimated:
            return []
        return [f"mill {self.name}: {', '.join(estimated)} {'are estimates' if len(estimated) > 1 else 'is an estimate'}, "
                f"not sourced figures (`taimill mills {self.name}` says whence)"]

    def as_dict(self) -> dict:
        """Plain data for a run's resolved configuration."""
        return {"name": self.name, "maker": self.maker, "model": self.model, "stations": self.stations,
                "plate_radius_mm": self.plate_radius * 1e3, "gear": self.gear.as_dict(),
                "plate_rpm_min": self.plate_rpm_min, "plate_rpm_max": self.plate_rpm_max, "bowls_ml": list(self.bowls_ml),
                "estimates": [o.key for o in self.origins if o.estimate]}


def mill_names() -> list[str]:
    """The bundled mills, by name."""
    return files.bundled_names("mill")


def load_mill(name_or_path: str = DEFAULT, source="preset", base: Path | None = None) -> Mill:
    """A mill by name (taimill/data/mills/NAME.toml) or from a mill file (.toml, relative
    to base: the current folder for the command line, the preset's folder for a preset)."""
    files.check_path_text(name_or_path, source, "mill", "a mill name or mill file")
    path = files.resolve(name_or_path, "mill", False, base, source=source, key="mill")
    if files.missing(path):
        raise ConfigError(source, "mill", name_or_path, f"no mill file {path}; known mills: {', '.join(mill_names())}")
    data = read_toml(path, "mill", source)
    files.check_kind(data, "mill", name_or_path, source, "mill")
    t = Table(data, path, known=MILL_KEYS)
    maker, model = t.get("maker", kind=str), t.get("model", kind=str)
    desc = t.get("description", "", kind=str)
    radius = t.get("plate_radius_mm", **RANGES["plate_radius_mm"].bounds) * 1e-3
    gear = _gear(t)
    lo = t.get("plate_rpm_min", None, lo=0, lo_open=True, hi=5000)
    hi = t.get("plate_rpm_max", None, lo=0, lo_open=True, hi=5000)
    if lo is not None and hi is not None and lo > hi:
        raise ConfigError(path, "plate_rpm_min", lo, f"must not exceed plate_rpm_max = {hi:g} rpm")
    stations = t.get("stations", kind=int, lo=1, hi=8)
    bowls = _bowls(t)
    origins = read_origins(t, tuple(k for k in NUMBERS if t.has(k)))
    t.done()
    return Mill(path.stem, str(path), maker, model, desc, radius, gear, lo, hi, stations, bowls, origins)


def _gear(t: Table) -> Gear:
    kind = t.get("gear", kind=str, allowed=GEARS)
    own = {"fixed": ("gear_ratio",), "set": ("gear_ratios",), "free": ("ratio_min", "ratio_max")}[kind]
    for key in ("gear_ratio", "gear_ratios", "ratio_min", "ratio_max"):
        if t.has(key) and key not in own:
            raise ConfigError(t.source, key, t.data[key], f"not used by gear = \"{kind}\"; it takes {' and '.join(own)}")
    if kind == "fixed":
        return Gear(kind, (t.get("gear_ratio", lo=-10, hi=10),))
    if kind == "set":
        raw = _list(t, "gear_ratios")
        if not isinstance(raw, list) or not raw or not all(isinstance(r, (int, float)) and not isinstance(r, bool) and math.isfinite(r) and -10 <= r <= 10
                              for r in raw):
            raise ConfigError(t.source, "gear_ratios", raw, "must be a non-empty list of the maker's r of \"1:r\", each in [-10, 10]")
        return Gear(kind, tuple(float(r) for r in raw))
    k = RANGES["ratio"]
    lo, hi = t.get("ratio_min", None, lo=k.lo, hi=k.hi), t.get("ratio_max", None, lo=k.lo, hi=k.hi)
    if lo is not None and hi is not None and lo > hi:
        raise ConfigError(t.source, "ratio_min", lo, f"must not exceed ratio_max = {hi:g}")
    return Gear(kind, (), lo, hi)


def _bowls(t: Table) -> tuple[int, ...]:
    raw = _list(t, "bowls_ml")
    if not isinstance(raw, list) or not all(isinstance(v, int) and not isinstance(v, bool) and 10 <= v <= 1000 for v in raw) or len(set(raw)) != len(raw):
        raise ConfigError(t.source, "bowls_ml", raw, "must be a list of distinct whole volumes in ml, each in [10, 1000]")
    return tuple(sorted(raw))


def _list(t: Table, key: str):
    """t's value at key ([] if not set), for the caller to check it is a list of what it needs."""
    t.used.add(key)
    return t.data.get(key, [])


def bowl_estimates(mill: Mill, path: Path, source) -> list[str]:
    """A warning line if the bowl file at path gives estimated sizes ([estimates])."""
    notes = read_toml(path, "bowl", source).get("estimates") if not files.missing(path) else None
    if not isinstance(notes, dict) or not notes:
        return []
    return [f"bowl {path.stem} of mill {mill.name}: {', '.join(notes)} estimated, not measured (see {path})"]


def bowl_path(mill: Mill, volume_ml, source="command line", key="jar_volume_ml") -> Path:
    """The bowl file of a mill's maker for one of its volumes:
    taimill/data/bowls/{maker}-{volume}ml.toml; a volume the mill does not take is refused
    naming those it does."""
    ok = not isinstance(volume_ml, bool) and isinstance(volume_ml, (int, float)) and volume_ml in mill.bowls_ml
    if not ok:
        allowed = ", ".join(f"{v:d}" for v in mill.bowls_ml) or "none listed"
        raise ConfigError(source, key, volume_ml, f"mill {mill.name} takes bowls of {allowed} ml")
    return files.BUNDLED["jar"][-1] / f"{mill.maker.lower()}-{int(volume_ml)}ml.toml"  # the bowls folder
