"""What a taimill recording looks like: entity paths, static scenery, colour scales and
the default blueprint (rerun-sdk 0.41).

Entity tree (SI units: m, s, J, W, except stress energies in mJ, as in the reports, with
the unit in their names: /stats/mean_se_mJ/…, "up to … mJ"):

    /jar                     the jar frame (docs/model.md); in the lab view its pose on the plate
    /jar/wall                the jar's real profile at floor and lid, with vertical edges
    /jar/floor               the floor, a triangle fan over the (star-shaped) profile
    /jar/balls               Points3D per frame: centres (jar frame), radii, colour = speed
    /jar/impacts/normal      one point per event at its contact point and t_start,
    /jar/impacts/tangential  coloured and sized by SE_n resp. SE_t; the 3-D view shows the
                             last IMPACT_LIFE seconds of them. Both sit at the same points,
                             so the tangential ones start hidden (one click shows them)
    /jar/contact_map         ball-wall events, coloured by u̇_n, shown accumulated
    /plate                   lab frame only: the plate rim and the jar's path
    /stats/...               scalar series (stats.py)
    /histograms/onset_{normal,tangential}   BarCharts over log10 onset speed in mm/s (as the reports)
    /run/info                the resolved preset and, at the end, the summary

Colour scales are fixed per run so colours mean the same at every time: speeds relative
to V = max(|Ω - w| R_jar, √(4 g R_jar)) — the wall's speed relative to the rotating
centrifugal field, or a free fall across the jar — and stress energies relative to
½ m_ball V², over SE_DECADES decades.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from taimill.model.drive import Drive
from taimill.model.geometry import build_profile
from taimill.recording.stats import hist_edges

JAR, WALL, FLOOR, BALLS = "/jar", "/jar/wall", "/jar/floor", "/jar/balls"
IMPACTS = {"normal": "/jar/impacts/normal", "tangential": "/jar/impacts/tangential"}
CONTACT_MAP, PLATE, INFO = "/jar/contact_map", "/plate", "/run/info"
HISTOGRAMS = {"normal": "/histograms/onset_normal", "tangential": "/histograms/onset_tangential"}
TIME, STEP = "sim_time", "step"

IMPACT_LIFE = 0.02  # s an impact stays visible in the 3-D view (2 frames at 100 Hz)
SE_DECADES = 4.0  # colour range of stress energies below ½ m V²
UN_DECADES = 2.0  # colour range of contact-map onset speeds below V (wall impacts: ≈ V/50 … V)
OUTLINE_POINTS = 720  # profile vertices drawn (of the fine outline's thousands)
EDGES = 24  # vertical wall edges drawn
TOTAL_COLOUR = [235, 195, 60, 255]  # the mean-SE total, apart from its normal (plasma) and tangential (cool) parts
COLORMAPS = {"speed": "viridis", "normal": "plasma", "tangential": "cool", "contact": "turbo"}

# series path -> (plot, legend name, unit)
SERIES = {
    "impact_power/normal": ("impact power", "normal", "W"),
    "impact_power/tangential": ("impact power", "tangential", "W"),
    "mean_se_mJ/total": ("mean stress energy", "total (mJ)", "mJ"),
    "mean_se_mJ/normal": ("mean stress energy", "normal (mJ)", "mJ"),
    "mean_se_mJ/tangential": ("mean stress energy", "tangential (mJ)", "mJ"),
    "collision_rate": ("stress-event rate", "events/s", "1/s"),
    "dissipated_power": ("dissipated power", "dissipated", "W"),
    "dissipated_power_persistent": ("dissipated power", "in persistent contacts", "W"),
    "kinetic_energy": ("kinetic energy", "ground frame", "J"),
    "energy_balance_error": ("energy balance error", "relative", "-"),
}


@functools.lru_cache(maxsize=None)
def lut(name: str) -> np.ndarray:
    """(256, 4) uint8 RGBA table of a matplotlib colormap."""
    from matplotlib import colormaps

    return (colormaps[name](np.linspace(0.0, 1.0, 256)) * 255).round().astype(np.uint8)


def shade(table: np.ndarray, value: np.ndarray) -> np.ndarray:
    """Colours of `value` in [0, 1] (clipped) from a LUT."""
    return table[(np.clip(value, 0.0, 1.0) * 255).astype(np.intp)]


def log_scale(x: np.ndarray, ref: float, decades: float) -> np.ndarray:
    """0 at ref·10^-decades (and below), 1 at ref."""
    with np.errstate(divide="ignore"):
        return np.clip(1.0 + np.log10(np.maximum(x, 0.0) / ref) / decades, 0.0, 1.0)


def jar_outline(config: dict) -> np.ndarray:
    """The jar profile's fine closed outline (M, 2), m, rebuilt from the resolved preset."""
    jar = config["jar"]
    return build_profile(jar["primitives"], jar["fillet"]).outline


def speed_scale(config: dict, radius: float) -> float:
    """V (m/s), see the module doc; `radius` the jar's bounding radius (m)."""
    relative = abs(Drive.from_config(config).relative_spin) * radius
    return max(relative, math.sqrt(4.0 * config["gravity"] * radius))


def ball_mass(config: dict) -> float:
    """Mass of one ball (kg) from the resolved preset."""
    b = config["balls"]
    return b["material"]["density"] * 4.0 / 3.0 * math.pi * b["radius"] ** 3


# ---------------------------------------------------------------- static scenery
def ring(fine: np.ndarray) -> np.ndarray:
    """(OUTLINE_POINTS, 2) vertices picked from a fine outline (m), closed by the caller."""
    return fine[np.linspace(0, len(fine), OUTLINE_POINTS, endpoint=False).astype(int)]


def jar_strips(vertices: np.ndarray, height: float) -> list[np.ndarray]:
    """Floor and lid rings and EDGES vertical edges, as 3-D line strips (m)."""
    closed = np.vstack([vertices, vertices[:1]])
    floor = np.column_stack([closed, np.zeros(len(closed))])
    lid = np.column_stack([closed, np.full(len(closed), height)])
    edges = [np.array([[*p, 0.0], [*p, height]]) for p in vertices[:: max(1, len(vertices) // EDGES)]]
    return [floor, lid, *edges]


def floor_mesh(vertices: np.ndarray) -> rr.Mesh3D:
    """Triangle fan from the axis: valid because profiles are star-shaped (taimill.model.geometry)."""
    n = len(vertices)
    points = np.vstack([[0.0, 0.0, 0.0], np.column_stack([vertices, np.zeros(n)])])
    i = np.arange(1, n + 1)
    triangles = np.column_stack([np.zeros_like(i), i, i % n + 1])
    return rr.Mesh3D(vertex_positions=points, triangle_indices=triangles, albedo_factor=[70, 70, 80, 255])


def plate_strips(plate_radius: float, jar_radius: float) -> list[np.ndarray]:
    """Plate rim (jar path + 1.2 jar radii) and the path of the jar axis (m)."""
    a = np.linspace(0.0, 2.0 * math.pi, 361)
    circle = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    return [circle * (plate_radius + 1.2 * jar_radius), circle * plate_radius]


def log_scenery(rec: rr.RecordingStream, config: dict, fine: np.ndarray, radii: np.ndarray, lab_frame: bool) -> None:
    """Everything logged once (static): axes, jar (`fine`: jar_outline), ball radii (m),
    plate, series names."""
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    vertices = ring(fine)
    rec.log(WALL, rr.LineStrips3D(jar_strips(vertices, config["jar"]["height"]), radii=rr.Radius.ui_points(1.0),
                                  colors=[150, 160, 175, 255]), static=True)
    rec.log(FLOOR, floor_mesh(vertices), static=True)
    rec.log(BALLS, rr.Points3D.from_fields(radii=np.asarray(radii, dtype=np.float32)), static=True)
    if lab_frame:
        jar_radius = float(np.hypot(*fine.T).max())
        rec.log(PLATE, rr.LineStrips3D(plate_strips(config["plate_radius"], jar_radius), radii=rr.Radius.ui_points(1.0),
                                       colors=[120, 120, 120, 255]), static=True)
    for path, (_, name, _) in SERIES.items():
        kind = path.rpartition("/")[2]
        color = shade(lut(COLORMAPS[kind]), np.array(0.6)) if kind in IMPACTS else TOTAL_COLOUR if kind == "total" else None
        rec.log(f"/stats/{path}", rr.SeriesLines(names=name, colors=color), static=True)


def info_text(config: dict, speed_ref: float, se_ref: float, summary: dict | None = None,
              status: str | None = None) -> str:
    """Markdown: the run's setting and colour scales (m/s, mJ), and its summary once finished
    (its JSON keys and SI units, as `taimill run --json`)."""
    jar, balls = config["jar"], config["balls"]
    drive = Drive.from_config(config)
    lines = [
        f"# {config.get('source', 'taimill run')}",
        f"- jar **{jar['name']}**, {balls['count']} × {balls['material']['name']} balls of "
        f"{balls['radius'] * 1e3:g} mm, pair **{config['pair']}**",
        f"- Ω = {drive.plate_rpm:g} rpm, K = {drive.ratio:.3g}, dt = {config['dt'] * 1e6:.4g} µs, duration {config.get('duration', '?')} s",
        f"- balls coloured by speed in the jar frame ({COLORMAPS['speed']}, 0 … {speed_ref:.2f} m/s)",
        f"- impacts by stress energy (normal {COLORMAPS['normal']}, tangential {COLORMAPS['tangential']}; "
        f"{SE_DECADES:g} decades up to {se_ref * 1e3:.3g} mJ), shown for {IMPACT_LIFE * 1e3:g} ms",
        f"- contact map by onset u̇_n ({COLORMAPS['contact']}, {UN_DECADES:g} decades up to {speed_ref:.2f} m/s)",
    ]
    if summary:
        units = summary.get("units", {})
        lines += ["", f"## Summary ({status})", "", "| key | value | unit |", "|---|---|---|"]
        lines += [_summary_row(k, v, units.get(k, "")) for k, v in summary.items() if k != "units"]
    return "\n".join(lines)


def _summary_row(key: str, value, unit: str) -> str:
    """A row of the summary table; stress energies (`…se…` keys in J) in mJ."""
    if isinstance(value, float) and unit == "J" and "se" in key.split("_"):
        value, unit = value * 1e3, "mJ"
    return f"| {key} | {value:.6g} | {unit} |" if isinstance(value, float) else f"| {key} | {value} | {unit} |"


HIST_ABSCISSA_SHIFT = 3.0  # log10(m/s) + 3 = log10(mm/s)


def histogram(kind: str, shares: np.ndarray) -> rr.BarChart:
    """Bars over the log10 onset-speed bins, coloured per kind. The abscissa is log10 of
    the speed in mm/s (−1 … 4), the unit of the reports' onset-speed figures and of the
    stress-event threshold (10 mm/s sits at 1).
    (Whole rows: BarChart.from_fields without values fails in rerun-sdk 0.41.)"""
    edges = hist_edges() + HIST_ABSCISSA_SHIFT
    return rr.BarChart(shares, abscissa=0.5 * (edges[1:] + edges[:-1]), widths=np.diff(edges),
                       color=shade(lut(COLORMAPS[kind]), np.array(0.6)))


# ---------------------------------------------------------------- blueprint
def recent(seconds: float) -> rrb.VisibleTimeRanges:
    return rrb.VisibleTimeRanges(timeline=TIME, start=rrb.TimeRangeBoundary.cursor_relative(seconds=-seconds),
                                 end=rrb.TimeRangeBoundary.cursor_relative())


# The jar view's camera: seen from EYE_AZIMUTH (deg, from +x) and EYE_ELEVATION above
# the floor plane, at EYE_DISTANCE times the radius of the jar's bounding sphere from its
# centre: the whole jar stays in view in the recording's narrow (portrait) panel, whose
# horizontal field of view is ≈ 45° (the viewer's own choice zooms into the balls).
EYE_AZIMUTH, EYE_ELEVATION, EYE_DISTANCE = -60.0, 35.0, 3.2


def jar_eye(radius: float, height: float) -> rrb.EyeControls3D:
    """Orbit camera on the jar's centre (jar frame, m) showing the whole jar."""
    centre = np.array([0.0, 0.0, 0.5 * height])
    d = EYE_DISTANCE * math.hypot(radius, 0.5 * height)
    az, el = math.radians(EYE_AZIMUTH), math.radians(EYE_ELEVATION)
    eye = centre + d * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    return rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=eye, look_target=centre, eye_up=[0.0, 0.0, 1.0])


def extent_of(config: dict) -> tuple[float, float]:
    """(bounding radius, height) of the jar of a resolved preset (m)."""
    return float(np.hypot(*jar_outline(config).T).max()), float(config["jar"]["height"])


def recorded_extent(rrd) -> tuple[float, float] | None:
    """(bounding radius, height) of the jar drawn in a recording (its /jar/wall strips,
    m), or None if it has none."""
    for chunk in rr.chunk.RrdReader(str(rrd)).stream().to_chunks():
        if str(chunk.entity_path) == WALL:
            batch = chunk.to_record_batch()
            strips = batch.column(batch.schema.get_field_index("LineStrips3D:strips")).to_pylist()
            xyz = np.array([p for row in strips if row for strip in row for p in strip], dtype=float)
            if len(xyz):
                return float(np.hypot(xyz[:, 0], xyz[:, 1]).max()), float(xyz[:, 2].max())
    return None


def blueprint(lab_frame: bool, extent: tuple[float, float] | None = None) -> rrb.Blueprint:
    """3-D views (jar frame; lab frame if recorded), the time series in a grid, the
    histograms and the accumulated contact map. extent: the jar's (bounding radius,
    height) in m (`extent_of`), for a camera showing the whole jar."""
    jar_view = rrb.Spatial3DView(
        origin=JAR, name="jar frame: balls by speed, impacts by SE",
        contents=[f"+ {WALL}", f"+ {FLOOR}", f"+ {BALLS}", "+ /jar/impacts/**"],
        overrides={IMPACTS["normal"]: recent(IMPACT_LIFE),  # tangential: same points, off until toggled
                   IMPACTS["tangential"]: [recent(IMPACT_LIFE), rrb.EntityBehavior(visible=False)]},
        eye_controls=jar_eye(*extent) if extent else None,
    )
    views = [jar_view]
    if lab_frame:
        views.append(rrb.Spatial3DView(origin="/", name="lab frame: plate and jar",
                                       contents=[f"+ {PLATE}", f"+ {WALL}", f"+ {FLOOR}", f"+ {BALLS}"]))
    plots = {}
    for path, (plot, _, unit) in SERIES.items():
        plots.setdefault(plot, []).append(path)
    series = [rrb.TimeSeriesView(origin="/stats", name=f"{plot} ({unit})",
                                 contents=[f"+ /stats/{p}" for p in paths])
              for (plot, paths), unit in zip(plots.items(), [SERIES[p[0]][2] for p in plots.values()])]
    contact_map = rrb.Spatial3DView(
        origin=JAR, name="ball-jar contact map (u̇_n)", contents=[f"+ {CONTACT_MAP}", f"+ {WALL}"],
        time_ranges=rrb.VisibleTimeRanges(timeline=TIME, start=rrb.TimeRangeBoundary.infinite(),
                                          end=rrb.TimeRangeBoundary.cursor_relative()),
    )
    bars = [rrb.BarChartView(origin=path, name=f"onset u̇_{kind[0]}: share per bin of log10(u̇_{kind[0]} in mm/s)")
            for kind, path in HISTOGRAMS.items()]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(*views),
            rrb.Grid(*series, grid_columns=2),
            rrb.Vertical(*bars, rrb.Tabs(contact_map, rrb.TextDocumentView(origin=INFO, name="run"))),
            column_shares=[2.0, 2.0, 1.4],
        ),
        rrb.TimePanel(timeline=TIME, state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )
