"""`dkreason plot` (features over time) and `monitor --plot` (what the monitor said, drawn)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from dkreason import FeatureKey, KnowledgeManager
from dkreason.cli import main
from dkreason.parse.formula import parse_formula
from dkreason.plot import concerned, thresholds
from dkreason.progress import Verdict
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.processor import Violation
from dkreason.stream.recording import write_recording

from .test_init import TYPES, rows
from .test_monitor import CAR1, CAR2, SLOW, SPEEDING, car_rows
from .test_monitor import TYPES as CAR_TYPES

REPO = Path(__file__).resolve().parents[1]
MAGIC = {".png": b"\x89PNG", ".svg": b"<?xml", ".pdf": b"%PDF"}


@pytest.mark.parametrize("suffix", [".png", ".svg", ".pdf"])
def test_plot_draws_numbers_booleans_and_strings(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, suffix: str
) -> None:
    bag = tmp_path / "rover.bag"
    write_recording(bag, "ros1", TYPES, rows())
    config = KnowledgeManager.init([bag], tmp_path, robot="rover").config
    out = tmp_path / f"features{suffix}"
    features = ["RoverBatteryPercentage[rover]", "RoverBatteryCharging[rover]"]
    features.append("RoverBatteryStatus[rover]")
    code = main(["plot", "--config", str(config), "--source", str(bag), "-o", str(out), *features])
    assert code == 0 and out.read_bytes().startswith(MAGIC[suffix])
    assert main(["plot", "--config", str(config), "--source", str(bag), "-o", str(out), "x)"]) == 2
    assert "expected a ground feature, like Speed[car1]" in capsys.readouterr().err


def test_thresholds_are_the_constants_features_are_compared_with() -> None:
    tree = parse_formula("always (Speed[car1] > 60 -> eventually[0, 3] 60 >= Speed[car1])")
    car1 = FeatureKey("Speed", ("car1",))
    assert thresholds([tree]) == [(car1, ">", 60.0), (car1, "<=", 60.0)]


def test_a_plot_that_fails_is_one_line_and_keeps_the_exit_status(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import dkreason.plot

    def broken(*_: object) -> None:
        raise RuntimeError("no fonts\nat all")

    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", CAR_TYPES, car_rows())
    args = ["monitor", "--config", str(REPO / "examples" / "single.toml"), "--source", str(source)]
    out = tmp_path / "run.png"
    assert main([*args, "--plot", str(out), SPEEDING, SLOW]) == 1
    assert out.read_bytes().startswith(MAGIC[".png"])
    monkeypatch.setattr(dkreason.plot, "plot", broken)
    assert main([*args, "--plot", str(out), SPEEDING, SLOW]) == 1
    assert capsys.readouterr().err == f"error: --plot {out}: no fonts\\nat all\n"


def test_a_violated_quantified_formula_is_drawn_on_the_violating_objects_panels_only(
    tmp_path: Path,
) -> None:
    """`forall c in Car`: car1 speeds, car2 keeps to 50; the violation and its witness window
    are drawn on Speed[car1]'s panel, not on every car's."""
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", CAR_TYPES, car_rows())
    km = KnowledgeManager.from_config(REPO / "examples" / "single.toml")
    formula = "forall c in Car: always (Speed[c] > 60 -> eventually[0, 3] Speed[c] <= 60)"
    (plan,) = km.plan(formula).formulas
    (verdict,) = [e for e in km.monitor(formula, source) if isinstance(e, Verdict)][:1]
    assert verdict.verdict is False
    drawn = concerned(plan, verdict)
    assert CAR1 in drawn and CAR2 not in drawn


def test_robustness_gets_its_own_panel(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With --robustness, --plot draws each formula's margin at every state below the
    features; without it, no such panel."""
    import matplotlib

    monkeypatch.setitem(matplotlib.rcParams, "svg.fonttype", "none")  # text kept as text
    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", CAR_TYPES, car_rows())
    args = ["monitor", "--config", str(REPO / "examples" / "single.toml"), "--source", str(source)]
    for robust, out in ((True, tmp_path / "with.svg"), (False, tmp_path / "without.svg")):
        flags = ["--robustness"] if robust else []
        assert main([*args, *flags, "--plot", str(out), SLOW]) == 0
        drawn = out.read_text()
        assert "Speed[car2]" in drawn and ("#1 robustness" in drawn) is robust


def test_stream_constraint_violations_are_ticks_on_the_panels_edge_not_new_y_values(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every sample of car1 comes a second after the one before, twice the period asked for:
    the violations are drawn along the bottom edge of Speed[car1]'s panel, whose y range stays
    its values' and the threshold's (50 to 100), however many there are."""
    import dkreason.plot

    source = tmp_path / "run.mcap"
    write_recording(source, "bare-mcap", CAR_TYPES, car_rows(20))
    km = KnowledgeManager.from_config(REPO / "examples" / "single.toml")
    policy = StreamPolicy(sample_period=Fraction(1, 2), sample_period_deviation=Fraction(1, 10))
    formula = "always (Speed[car1] < 100)"
    with km.monitor(formula, source, policy, keep_states=True) as run:
        events = list(run)
        assert sum(isinstance(e, Violation) for e in events) > 10
        figures: list[Any] = []
        monkeypatch.setattr(dkreason.plot, "_save", lambda fig, _: figures.append(fig))
        dkreason.plot.plot(run, events, tmp_path / "run.png")
    (fig,) = figures
    (ax,) = [ax for ax in fig.axes if ax.get_ylabel() == "Speed[car1]"]
    low, high = ax.get_ylim()
    assert 40 <= low < 50 and 100 < high < 120  # the values and the threshold, nothing below
