"""What a newcomer sees of the CLI: the progress bar of `taimill run` says when it
compiles before it counts seconds."""

import io
from pathlib import Path

from rich.console import Console

from taimill.cli.run import _run_with_bar
from taimill.model.params import load_preset

ROOT = Path(__file__).resolve().parent.parent
PRESET = ROOT / "presets" / "p4-cy-steel.toml"


def test_progress_bar_says_it_compiles_before_it_counts_simulated_seconds():
    seen = []
    text = io.StringIO()
    console = Console(file=text, force_terminal=True, width=100)

    def run(preset, sink, progress):  # as runs.simulation.run: the first report comes after compilation
        seen.append(text.getvalue())
        progress(0.25)
        progress(0.5)
        return {"done": True}

    assert _run_with_bar(run, load_preset(PRESET, {"duration": 0.5}), None, console=console) == {"done": True}
    assert "compiling kernels" in seen[0] and "0.00/" not in seen[0]
    assert "simulating" in text.getvalue() and "0.50/0.5 s" in text.getvalue()
