"""What a newcomer sees of the CLI: JSON outputs carry the units of their numbers
(docs/outputs.md), `taimill presets` shows each preset's whole first sentence, and the
progress bar of `taimill run` says when it compiles before it counts seconds."""

import io
import json
import re
import subprocess
import sys
from pathlib import Path

from rich.console import Console

from helpers import numbers_without_unit
from taimill.cli import main
from taimill.cli.catalog import first_sentence
from taimill.cli.run import _run_with_bar
from taimill.model.preset import load_preset
from taimill.schema import SUMMARY_UNITS, units_of
from taimill.store.run import open_run

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "presets" / "p4-cy-steel.toml"


def taimill(*args):
    return subprocess.run([sys.executable, "-m", "taimill.cli", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


def test_units_of_finds_keys_in_nested_objects_and_stops_at_an_object_with_one_unit():
    s = {"mean_se": 1e-3, "all_contacts": {"collision_rate": 3.0}, "regime": "cascading",
         "dissipation_by_mechanism": {"side": {"impact": {"friction": 0.1}}}, "live_changes": [{"time": 1.0}]}
    assert units_of(s) == {"collision_rate": "1/s", "dissipation_by_mechanism": "W", "mean_se": "J", "time": "s"}
    assert "friction" not in SUMMARY_UNITS  # W in dissipation_by_mechanism, J in wall_energy: listed by object


def test_run_and_analyse_json_and_the_stored_summary_carry_units(tmp_path):
    out = tmp_path / "run.zarr"
    res = taimill("run", PRESET, "--duration", 0.3, "--json", "--out", out)
    assert res.returncode == 0, res.stderr
    assert "[Taichi]" not in res.stderr  # Taichi's start line is not printed
    summary = json.loads(res.stdout)
    assert summary["units"]["mean_se"] == "J" and summary["units"]["plate_rpm"] == "rpm"
    assert summary["units"]["energy_balance_error"] == "1"  # a fraction, not %
    assert numbers_without_unit(summary) == []
    assert open_run(out).summary["units"] == summary["units"]
    res = taimill("analyse", out, "--json")
    assert res.returncode == 0, res.stderr
    q = json.loads(res.stdout)
    assert q["units"]["r_edges"] == "m" and q["units"]["wall_energy"] == "J"
    assert numbers_without_unit(q) == []


def test_progress_bar_names_the_set_up_phases_and_says_it_compiles_before_it_counts_simulated_seconds():
    seen = []
    text = io.StringIO()
    console = Console(file=text, force_terminal=True, width=100)

    def run(preset, sink, progress, stage, notice):  # as runs.simulation.run: the first report comes after compilation
        seen.append(text.getvalue())
        stage("compiling kernels for 12 balls (first run of this size, ≈ 20 s)…")
        notice("compiling kernels for 12 balls (first run of this size, ≈ 20 s)")
        seen.append(text.getvalue())
        progress(0.25)
        progress(0.5)
        return {"done": True}

    assert _run_with_bar(run, load_preset(PRESET, {"duration": 0.5}), None, console=console) == {"done": True}
    assert "setting up 12 balls" in seen[0] and "0.00/" not in seen[0]
    assert "compiling kernels" in seen[1][len(seen[0]):] and "0.00/" not in seen[1]
    assert "simulating" in text.getvalue() and "0.50/0.5 s" in text.getvalue()
    # the notice is a line of its own that stays when the (transient) bar is gone
    assert "taimill: compiling kernels for 12 balls (first run of this size, ≈ 20 s)\n" in text.getvalue()


def test_run_reports_its_set_up_phases_before_the_first_launch(monkeypatch):
    from taimill.physics import runner
    from taimill.runs import simulation

    events, notices = [], []
    monkeypatch.setattr(simulation.Runner, "run", lambda self, sinks, progress=None: events.append("first launch"))
    monkeypatch.setattr(runner, "_engines", {})  # a process without kernels: they are compiled
    preset = load_preset(PRESET, {"duration": 0.01})
    simulation.run(preset, stage=events.append, notice=notices.append)
    assert events[0].startswith("placing 12 balls") and events[1].startswith("setting up 12 balls")
    assert events[2].startswith("compiling kernels for 12 balls (") and events[2].endswith(" s)…")
    assert events[3].startswith("first neighbour lists") and events[4] == "first launch"
    assert notices == [events[2][:-1]]
    events.clear(), notices.clear()
    simulation.run(preset, stage=events.append, notice=notices.append)  # the kernels are there now
    assert not any("compiling" in e for e in events) and notices == []


def presets_listing(capsys) -> dict[str, str]:
    capsys.readouterr()
    assert main(["presets", "--describe"]) == 0
    out = capsys.readouterr().out
    entries = re.split(r"\n(?=\S)", out.strip())
    return {e.split()[0]: " ".join(e.split()[1:]) for e in entries}


def test_presets_shows_whole_first_sentences(capsys):
    listing = presets_listing(capsys)
    files = sorted((ROOT / "presets").glob("*.toml"))
    assert sorted(listing) == [p.stem for p in files]
    for p in files:
        text = listing[p.stem]
        assert text == first_sentence(p) and text.endswith(".")
        comment = " ".join(line.lstrip("# ").strip() for line in p.read_text().splitlines() if line.startswith("#"))
        assert comment.startswith(text)  # nothing cut from the start of the comment


def test_efv_presets_read_differently_and_name_their_pair_and_speed(capsys):
    efv = {name: text for name, text in presets_listing(capsys).items() if name.startswith("efv-")}
    assert len(efv) == 4 and len(set(efv.values())) == 4
    for name, text in efv.items():
        pair = "zirconia-efavirenz" if "efavirenz" in name else "zirconia-zirconia"
        rpm = re.search(r"(\d+)rpm", name).group(1)
        assert pair in text and f"{rpm} rpm" in text
