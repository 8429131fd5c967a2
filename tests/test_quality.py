"""Streams with declared quality (issue 31; thesis 8.2): specs state a topic's rate and delay,
matching vetoes a topic whose delay exceeds the monitor's --max-delay and ranks a feature's
topics by what they declare, explanations cite it."""

from __future__ import annotations

import json
import random
from collections import Counter
from fractions import Fraction
from pathlib import Path
from typing import Any

import pytest

from dkreason import KnowledgeManager
from dkreason.cli import main
from dkreason.model import FeatureRequest, stream_name
from dkreason.monitor import Rerouted
from dkreason.progress import Verdict
from dkreason.stream.policy import StreamPolicy
from dkreason.stream.processor import Violation
from dkreason.stream.recording import Row, write_recording

from .conftest import REPO, SCENARIOS
from .test_foxglove import read_mcap

ALTITUDE = "always (Altitude[uav1] > 1)"
# topic1: its freshest sample at most 1.02 s old; topic2: 220 ms, but it lags 200 ms
SLOW = "topic1:UavMsg [rate 1 Hz, delay 20ms]"
LAGGING = "topic2:UavMsg [rate 50 Hz, delay 200ms]"


def declare(scenario: Path, *brackets: str) -> Path:
    """The single-platform scenario with these topics' quality declared; its config."""
    specs = scenario / "specs" / "platform1.sslt"
    text = specs.read_text(encoding="utf-8")
    for bracket in brackets:
        head = bracket.split(" [")[0]
        text = text.replace(f"topic {head} contains", f"topic {bracket} contains")
    specs.write_text(text, encoding="utf-8")
    return scenario / "single.toml"


def topics(features: tuple[FeatureRequest, ...]) -> list[str]:
    (feature,) = features
    return [t.topic for t in feature.topics]


def test_the_thesis_scenarios_declare_nothing_and_match_as_before(scenario: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "federation.toml")
    assert km.stored().get("topic_property", ("input", 0))[1] == 0
    plain = km.check_formula("always (Altitude[uav1] > Altitude[uav2])")
    assert (
        km.check_formula("always (Altitude[uav1] > Altitude[uav2])", max_delay="1ms").to_json()
        == plain.to_json()
    )
    assert not any(
        line.startswith(("rank", "age"))
        for f in km.explain(ALTITUDE).features
        for w in f.why
        for line in w.summary
    )


def test_declared_properties_are_facts_in_nanoseconds(scenario: Path) -> None:
    km = KnowledgeManager.from_config(declare(scenario, SLOW))
    rows = km.query("topic_property(P, 'topic1', Property, Value)").rows
    assert sorted(rows) == [
        ("platform1", "age", 1_020_000_000),
        ("platform1", "delay", 20_000_000),
        ("platform1", "period", 1_000_000_000),
    ]


def test_topics_are_ranked_by_declared_quality_and_best_source_takes_the_best(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = declare(scenario, SLOW, LAGGING)
    km = KnowledgeManager.from_config(config)
    assert topics(km.check_formula(ALTITUDE).features) == ["topic2", "topic1"]  # merged
    assert topics(km.check_formula(ALTITUDE, best_source=True).features) == ["topic2"]
    assert main(["match", "--config", str(config), "--best-source", "--json", ALTITUDE]) == 0
    (feature,) = json.loads(capsys.readouterr().out)["features"]
    assert [t["topic"] for t in feature["topics"]] == ["topic2"]
    assert [t["topic"] for t in feature["standby"]] == ["topic1"]  # read, feeding nothing
    assert main(["match", "--config", str(config), "--best-source", ALTITUDE]) == 0
    out = capsys.readouterr().out
    assert "Standing by:\n  Topic: topic1, Message type: UavMsg" in out
    assert "Read from:\n  Topic: topic2, " in out and "Topics to merge" not in out
    assert "standby" not in km.check_formula(ALTITUDE).to_json()["features"][0]


def test_a_topic_declaring_nothing_comes_after_those_that_declare(scenario: Path) -> None:
    km = KnowledgeManager.from_config(declare(scenario, SLOW))
    assert topics(km.check_formula(ALTITUDE).features) == ["topic1", "topic2"]
    km = KnowledgeManager.from_config(declare(scenario, LAGGING))
    assert topics(km.check_formula(ALTITUDE, best_source=True).features) == ["topic2"]


def test_a_delay_over_max_delay_excludes_the_topic_with_an_explanation(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = declare(scenario, SLOW, LAGGING)
    km = KnowledgeManager.from_config(config)
    assert topics(km.check_formula(ALTITUDE, max_delay="100ms").features) == ["topic1"]
    assert topics(km.check_formula(ALTITUDE, max_delay=0.2).features) == ["topic2", "topic1"]
    (why_not,) = km.explain(ALTITUDE, topic="topic2", max_delay="100ms").features[0].why_not
    assert "[rules/quality.dl:" in why_not.reason
    assert "topic2 declares delay 200ms" in why_not.reason
    assert "the monitor's --max-delay is 100ms" in why_not.reason
    argv = ["explain", "--config", str(config), "--max-delay", "100ms", "--topic", "topic2"]
    assert main([*argv, ALTITUDE]) == 0
    assert "topic2 declares delay 200ms" in capsys.readouterr().out
    assert main(["match", "--config", str(config), "--max-delay", "0.1", "--json", ALTITUDE]) == 0
    (feature,) = json.loads(capsys.readouterr().out)["features"]
    assert [t["topic"] for t in feature["topics"]] == ["topic1"]


def test_an_absolute_topic_name_is_written_whole_beside_its_platform(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A ROS absolute name is not cut like an IRI (`fix` for `/gps/fix`) nor joined to its
    platform as `platform1//gps/fix`."""
    specs = scenario / "specs" / "platform1.sslt"
    specs.write_text(specs.read_text().replace("topic topic2:", "topic /gps/fix:"))
    km = own_rules(scenario, "excluded_topic(R, '/gps/fix') <= platform(R)\n")
    (why_not,) = km.explain(ALTITUDE, topic="/gps/fix").features[0].why_not
    assert why_not.reason.startswith("excluded_topic(platform1, /gps/fix) holds [own.dl:1]")
    plain = KnowledgeManager.from_config(scenario / "single.toml")
    why = {w.topic: w.summary for w in plain.explain(ALTITUDE).features[0].why}
    assert any(line.startswith("topic: /gps/fix carries Altitude") for line in why["/gps/fix"])
    path = scenario / "run.mcap"
    write_recording(path, "bare-mcap", TYPES, [("topic1", UAV, MS, {"id": 1, "alt": 2.0})])
    assert main(["info", "--config", str(scenario / "single.toml"), str(path)]) == 0
    assert "platform1:/gps/fix (UavMsg): in no recording" in capsys.readouterr().out
    assert stream_name("platform1", "/gps/fix") == "platform1:/gps/fix"
    assert stream_name("platform1", "gps/fix") == "platform1/gps/fix"


def test_explanations_cite_declared_properties_and_what_ranks_a_topic(scenario: Path) -> None:
    km = KnowledgeManager.from_config(declare(scenario, SLOW, LAGGING))
    why = {w.topic: w.summary for w in km.explain(ALTITUDE).features[0].why}
    assert "declared: rate 1 Hz, delay 20ms [" in "\n".join(why["topic1"])
    # the shipped rank is the declared age in nanoseconds: said as an age
    (ranked,) = [line for line in why["topic1"] if line.startswith("age")]
    assert ranked.startswith("age 1.02s: ") and "topic1 declares age 1.02s" in ranked
    (ranked,) = [line for line in why["topic2"] if line.startswith("age 220ms: ")]
    assert "topic2 declares age 220ms" in ranked


def own_rules(scenario: Path, text: str) -> KnowledgeManager:
    """The single-platform scenario with a rule file of one's own beside the shipped ones."""
    (scenario / "own.dl").write_text(text, encoding="utf-8")
    config = scenario / "own.toml"
    config.write_text(
        'rules = ["own.dl"]\n' + (scenario / "single.toml").read_text(encoding="utf-8")
    )
    return KnowledgeManager.from_config(config)


@pytest.mark.parametrize(
    "rule",
    [
        "rank(Q, R, T, D) <= declaring(R) & topic_property(R, T, 'delay', D) "
        "& wanted(Q, _F, _O1, _O2, _O3)",
        "topic_rank(R, T, D) <= declaring(R) & topic_property(R, T, 'delay', D)",
    ],
    ids=["per-formula", "per-topic"],
)
def test_a_rule_file_changes_the_ranking_without_python(scenario: Path, rule: str) -> None:
    """Rank by the declared delay alone: the smallest rank a topic gets is its rank."""
    declare(scenario, SLOW, LAGGING)
    km = own_rules(scenario, rule + "\n")
    assert topics(km.check_formula(ALTITUDE).features) == ["topic1", "topic2"]
    assert topics(km.check_formula(ALTITUDE, best_source=True).features) == ["topic1"]


def test_a_rule_file_excludes_a_topic_from_every_formula_with_an_explanation(
    scenario: Path,
) -> None:
    km = own_rules(scenario, "excluded_topic(R, T) <= topic(R, T, 'UavMsg') & (T != 'topic1')\n")
    assert topics(km.check_formula(ALTITUDE).features) == ["topic1"]
    (why_not,) = km.explain(ALTITUDE, topic="topic2").features[0].why_not
    assert why_not.reason.startswith("excluded_topic(platform1, topic2) holds [")
    assert "own.dl:1]" in why_not.reason


def test_a_monitors_max_delay_is_held_and_derives_again_only_what_reads_it(
    scenario: Path,
) -> None:
    """--max-delay is the knowledge base's while a monitor matches with it: the same one
    again derives nothing; another derives the exclusions and the topic tables only."""
    km = KnowledgeManager.from_config(declare(scenario, SLOW, LAGGING))
    kb = km.kb
    assert topics(km.check_formula(ALTITUDE, max_delay="100ms").features) == ["topic1"]
    assert {"excluded_topic", "topic_objects", "sort_arg_at"} <= set(kb.rederived)
    assert not {"topic_rank", "declares"} & set(kb.rederived)
    kb.rederived = []
    assert topics(km.check_formula(ALTITUDE, max_delay="100ms").features) == ["topic1"]
    assert kb.rederived == []
    assert topics(km.check_formula(ALTITUDE).features) == ["topic2", "topic1"]
    assert kb.engine.rows("max_delay") == []


def test_specs_add_and_show_take_and_show_declared_properties(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = str(scenario / "single.toml")
    spec = "topic fast:UavMsg [rate 100 Hz, delay 5ms] contains Altitude(uav2) = msg.alt"
    assert main(["specs", "add", "--config", config, spec]) == 0
    assert "[rate 100 Hz, delay 5ms]" in (scenario / "specs" / "platform1.sslt").read_text()
    capsys.readouterr()
    assert main(["specs", "show", "--config", config, "fast"]) == 0
    assert capsys.readouterr().out.strip() == spec
    assert main(["specs", "show", "--config", config, "--xml", "fast"]) == 0
    assert 'rate="100 Hz" delay="5ms"' in capsys.readouterr().out
    bad = "topic slow:UavMsg [rate -1 Hz] contains Altitude(uav2) = msg.alt"
    assert main(["specs", "add", "--config", config, bad]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: <topic>:1:25:") and "must be positive" in err and "\n" not in err


def test_a_window_finer_than_every_topics_period_is_one_warning_before_reading(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = declare(scenario, SLOW)
    km = KnowledgeManager.from_config(config)
    fine = "always (Speed[uav1] > 1 -> eventually[0, 50ms] Speed[uav1] < 1)"
    (warning,) = km.check_formula(fine).warnings
    assert warning == (
        f"{fine}: eventually[0, 0.05] is finer than the period of every topic of "
        "Speed[uav1] (topic1 at 1 Hz): a sample need not fall inside it"
    )
    assert not km.check_formula(fine.replace("50ms", "2")).warnings
    # Altitude[uav1] is also read from topic2, which declares no rate: no warning
    assert not km.check_formula("always eventually[0, 50ms] Altitude[uav1] > 1").warnings
    assert main(["match", "--config", str(config), fine]) == 0
    assert "Warning: " + warning in capsys.readouterr().out
    # with --json too, before the verdicts, as every other warning of the request
    path = scenario / "run.mcap"
    write_recording(path, "bare-mcap", TYPES, [("topic1", UAV, MS, {"id": 1, "spd": 2.0})])
    argv = ["monitor", "--config", str(config), "--source", str(path), "--json", fine]
    assert main(argv) == 3  # undecided: the data ends inside the window
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines[0] == {"warning": warning}


def test_a_feature_whose_topics_the_policy_excluded_is_one_warning_naming_them_and_why(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Left with no topic by --max-delay or by a rule file, a feature is not 'never seen' for
    lack of data: the request says which topics were excluded and by what."""
    config = declare(scenario, SLOW, LAGGING)
    km = KnowledgeManager.from_config(config)
    (warning,) = km.check_formula(ALTITUDE, max_delay="10ms").warnings
    assert warning.startswith("Altitude[uav1]: every topic of it is excluded by the policy: ")
    assert "platform1/topic1 (excluded_topic(platform1, topic1) holds [rules/quality.dl:" in warning
    assert "the monitor's --max-delay is 10ms, topic1 declares delay 20ms (platform1))" in warning
    assert "; platform1/topic2 (excluded_topic(platform1, topic2) holds [" in warning
    assert "\n" not in warning
    assert not km.check_formula(ALTITUDE, max_delay="100ms").warnings  # topic1 is left
    aside = frozenset({("platform1", "topic1"), ("platform1", "topic2")})
    (warning,) = km.request(km.plan(ALTITUDE), degraded=aside).warnings
    assert "platform1/topic1 (the monitor set topic1 aside on platform1: its samples" in warning
    ruled = own_rules(scenario, "excluded_topic(R, T) <= topic(R, T, 'UavMsg')\n")
    (warning,) = ruled.check_formula(ALTITUDE).warnings
    assert "platform1/topic2 (excluded_topic(platform1, topic2) holds [own.dl:1])" in warning
    argv = ["match", "--config", str(config), "--max-delay", "10ms", ALTITUDE]
    assert main(argv) == 0
    assert "Warning: Altitude[uav1]: every topic of it is excluded" in capsys.readouterr().out
    assert main([*argv[:-1], "--json", ALTITUDE]) == 0
    (said,) = json.loads(capsys.readouterr().out)["warnings"]
    assert said.startswith("Altitude[uav1]: every topic of it is excluded")
    path = scenario / "run.mcap"
    write_recording(path, "bare-mcap", TYPES, [("topic1", UAV, MS, {"id": 1, "alt": 2.0})])
    argv = ["monitor", "--config", str(config), "--source", str(path), "--max-delay", "10ms"]
    assert main([*argv, "--json", ALTITUDE]) == 3  # never seen
    first = json.loads(capsys.readouterr().out.splitlines()[0])
    assert first["warning"].startswith("Altitude[uav1]: every topic of it is excluded")


# ---- measured against declared ------------------------------------------------------------

MSGS = REPO / "examples" / "traffic" / "msg" / "dkreason_msgs" / "msg"
TYPES = {f"dkreason_msgs/msg/{p.stem}": p.read_text() for p in MSGS.glob("*.msg")}
AUTO, CAR = "dkreason_msgs/msg/AutomobileMsg", "dkreason_msgs/msg/CarMsg"
MS = 10**6


def declare_carstopic2(scenario: Path) -> None:
    """Platform 2's carstopic2 (car11's speed) declares 20 Hz and at most 50 ms of delay."""
    specs = scenario / "specs" / "platform2.sslt"
    specs.write_text(
        specs.read_text().replace(
            "carstopic2:AutomobileMsg contains",
            "carstopic2:AutomobileMsg [rate 20 Hz, delay 50ms] contains",
        )
    )


def car11(t_ns: int, lag_ns: int) -> Row:
    """car11 on platform 2's carstopic2, recorded at t_ns, stamped lag_ns earlier."""
    stamp = Fraction(t_ns - lag_ns, 10**9)
    return (
        "/platform2/carstopic2",
        AUTO,
        t_ns,
        {"header": {"stamp": stamp}, "id": 11, "speed": 50.0},
    )


def test_info_reports_each_topics_observed_rate_and_delay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    jitter = random.Random(31)
    rows = [car11(n * 50 * MS + jitter.randrange(-MS, MS), 30 * MS) for n in range(1, 201)]
    rows += [("topic3", CAR, n * 250 * MS, {"id": 1, "spd": 40.0}) for n in range(1, 41)]
    path = tmp_path / "run.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    (info,) = KnowledgeManager.describe([path], timing=True)
    timing = {t.name: t.timing for t in info.topics}
    cars, topic3 = timing["/platform2/carstopic2"], timing["topic3"]
    assert cars is not None and topic3 is not None
    assert cars.rate_median == pytest.approx(20, rel=0.02)
    assert cars.rate_p5 is not None and cars.rate_p5 < 20 * 0.98  # the jitter's slow moments
    assert cars.delay_median == pytest.approx(0.03, rel=0.02)
    assert cars.delay_p95 == pytest.approx(0.03, rel=0.02)
    assert topic3.rate_median == pytest.approx(4, rel=0.02)
    assert topic3.delay_median is None  # no header stamps
    assert main(["info", "--timing", "--json", str(path)]) == 0
    (shown,) = json.loads(capsys.readouterr().out)["recordings"]
    by_name = {t["topic"]: t for t in shown["topics"]}
    assert by_name["topic3"]["rate"]["median"] == pytest.approx(4, rel=0.02)
    assert main(["info", "--timing", str(path)]) == 0
    shown_text = capsys.readouterr().out
    assert "delay 0.03 s (p95 0.03)" in shown_text and "40  rate 4 Hz (p5 4)" in shown_text


def test_info_says_each_topics_longest_gap_and_with_a_config_what_it_declares(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A dropout the median rate hides: 20 Hz for 1 s, nothing for 5 s, 20 Hz again."""
    declare_carstopic2(scenario)
    rows = [car11(n * 50 * MS, 10 * MS) for n in range(1, 21)]
    rows += [car11(6_050 * MS + n * 50 * MS, 10 * MS) for n in range(20)]
    path = tmp_path / "run.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    (info,) = KnowledgeManager.describe([path], timing=True)
    (topic,) = info.topics
    assert (
        topic.gap is not None and topic.gap.length == 5_050 * MS and topic.gap.start == 1_000 * MS
    )
    config = str(scenario / "federation.toml")
    assert main(["info", "--timing", "--config", config, str(path)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "carstopic2  " in x)
    assert line.endswith(
        "rate 20 Hz (p5 20), delay 0.01 s (p95 0.01), longest gap 5.05 s at 0.95 s; "
        "declared rate 20 Hz, delay 50ms (platform2/carstopic2)"
    )
    assert main(["info", "--timing", "--json", "--config", config, str(path)]) == 0
    shown = json.loads(capsys.readouterr().out)
    (recorded,) = shown["recordings"][0]["topics"]
    assert recorded["longest_gap"] == {"seconds": 5.05, "from": 1.0}  # record time
    (bound,) = [b for b in shown["specs"] if b["topic"] == "carstopic2"]
    assert bound["rate"] == 20 and bound["delay"] == 0.05


def test_monitor_reports_a_topic_below_its_declared_rate_or_over_its_delay(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """carstopic2 declares 20 Hz and 50 ms; it runs at 20 Hz for 5 s, at 2 Hz for 5 s, and
    lags 80 ms over its last second.  Each kind is said at most once a second."""
    declare_carstopic2(scenario)
    rows = [car11(n * 50 * MS, 10 * MS) for n in range(1, 101)]
    rows += [car11(5_000 * MS + n * 500 * MS, (80 if n > 8 else 10) * MS) for n in range(1, 11)]
    path = tmp_path / "run.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    km = KnowledgeManager.from_config(scenario / "federation.toml")
    formula = "always (Speed[car1] < 100)"
    with km.monitor(formula, [path]) as run:
        found = [e for e in run if isinstance(e, Violation)]
    kinds = Counter(v.constraint for v in found)
    assert set(kinds) == {"declared_rate", "declared_delay"}
    assert 1 <= kinds["declared_rate"] <= 5 and kinds["declared_delay"] == 1
    first = next(v for v in found if v.constraint == "declared_rate")
    assert first.topic == "platform2/carstopic2" and str(first.feature) == "Speed[car1]"
    assert first.time > 5 and "below the declared 20 Hz" in first.detail
    (late,) = [v for v in found if v.constraint == "declared_delay"]
    assert late.detail == "delay 0.08 s exceeds 0.05 s"
    code = main(
        ["monitor", "--config", str(scenario / "federation.toml"), "--source", str(path), formula]
    )
    out = capsys.readouterr().out
    assert code == 0 and "declared_rate" in out and "declared_delay" in out


UAV = "dkreason_msgs/msg/UavMsg"
TEN_HZ = ("topic1:UavMsg [rate 10 Hz]", "topic2:UavMsg [rate 10 Hz]")


def stalled(tmp_path: Path) -> Path:
    """uav1's altitude on topic1 and topic2, both at 10 Hz for 6 s; topic1 sends nothing
    from 1.95 s to 4.05 s."""
    rows: list[Row] = [("topic2", UAV, n * 100 * MS, {"id": 1, "alt": 50.0}) for n in range(1, 61)]
    rows += [
        ("topic1", UAV, n * 100 * MS + 50 * MS, {"id": 1, "alt": 50.0})
        for n in range(1, 60)
        if not 20 <= n < 40
    ]
    path = tmp_path / "stalled.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    return path


def replayed(km: KnowledgeManager, path: Path, **policy: Any) -> list[Any]:
    with km.monitor(ALTITUDE, [path], StreamPolicy(**policy)) as run:
        return list(run)


def test_a_source_that_stops_is_set_aside_and_taken_back_when_it_sends_again(
    scenario: Path, tmp_path: Path
) -> None:
    """After three declared periods without a sample, topic1 is vetoed (rules/quality.dl's
    degraded/2) and uav1's altitude is read from topic2 alone; topic1's next sample takes it
    back.  The verdict goes on as it would have: nothing is restarted."""
    km = KnowledgeManager.from_config(declare(scenario, *TEN_HZ))
    path = stalled(tmp_path)
    events = replayed(km, path)
    moves = [e for e in events if isinstance(e, Rerouted)]
    both, two = ("platform1/topic1", "platform1/topic2"), ("platform1/topic2",)
    assert [(m.source, m.aside, m.before, m.after) for m in moves] == [
        ("platform1/topic1", True, both, two),
        ("platform1/topic1", False, two, both),
    ]
    aside, back = moves
    assert str(aside.feature) == "Altitude[uav1]" and 2.25 < aside.time <= 2.35
    assert aside.reason.startswith("no sample for 0.")
    assert aside.reason.endswith("over 3 periods of the declared 10 Hz")
    assert back.time == 4.05 and back.reason == "a sample came after 2.1 s without one"
    assert str(aside) == (
        "Altitude[uav1]: platform1/topic1 set aside (" + aside.reason + "); read from "
        "platform1/topic1 + platform1/topic2, now from platform1/topic2"
    )
    verdicts = [e for e in events if isinstance(e, Verdict)]
    assert verdicts == [e for e in replayed(km, path, set_aside_after=0) if isinstance(e, Verdict)]
    assert [e for e in replayed(km, path) if isinstance(e, Rerouted)] == moves  # the same data


def test_the_thesis_scenarios_set_nothing_aside(scenario: Path, tmp_path: Path) -> None:
    km = KnowledgeManager.from_config(scenario / "single.toml")
    assert not [e for e in replayed(km, stalled(tmp_path)) if isinstance(e, Rerouted)]


def test_monitor_says_each_reroute_in_a_line_and_in_json(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config, path = declare(scenario, *TEN_HZ), stalled(tmp_path)
    argv = ["monitor", "--config", str(config), "--source", str(path)]
    assert main([*argv, ALTITUDE]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "rerouted" in line]
    assert len(lines) == 2
    assert lines[1].startswith("rerouted at t+3.95 s (4.05 s): Altitude[uav1]: platform1/topic1")
    assert main([*argv, "--json", ALTITUDE]) == 0
    shown = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    moves = [e for e in shown if "rerouted" in e]
    assert [(m["rerouted"], m["change"], m["after"]) for m in moves] == [
        ("Altitude[uav1]", "set_aside", ["platform1/topic2"]),
        ("Altitude[uav1]", "taken_back", ["platform1/topic1", "platform1/topic2"]),
    ]
    kept = tmp_path / "kept.mcap"
    assert main([*argv, "--record", str(kept), ALTITUDE]) == 0
    capsys.readouterr()
    logs = [
        json.loads(data)["message"] for t, _, _, data in read_mcap(kept) if t == "/dkreason/log"
    ]
    assert sum("platform1/topic1 set aside" in line for line in logs) == 1
    assert main([*argv, "--set-aside-after", "0", ALTITUDE]) == 0
    assert "rerouted" not in capsys.readouterr().out
    with pytest.raises(SystemExit) as bad:
        main([*argv, "--set-aside-after", "x", ALTITUDE])
    assert bad.value.code == 2 and "--set-aside-after" in capsys.readouterr().err


def test_a_source_is_set_aside_past_n_declared_periods_without_a_sample_and_only_once() -> None:
    from dkreason.model import FeatureKey
    from dkreason.stream.quality import Move, QualityWatch

    moves: list[Move] = []
    watch = QualityWatch(3, moves.append)
    watch.declare(
        ("topic1", "/topic1"),  # the names it may be read by: one topic watched
        FeatureKey("Altitude", ("uav1",)),
        "platform1",
        "topic1",
        Fraction(10),
        None,
    )
    watch.sample("topic1", 1_000 * MS, 1_000 * MS)
    watch.silent(1_300 * MS)  # three periods: not yet
    assert moves == []
    watch.silent(1_301 * MS)
    watch.silent(1_500 * MS)
    assert [(m.topic, m.aside, m.time) for m in moves] == [("topic1", True, 1_301 * MS)]
    assert watch.aside() == ["topic1", "/topic1"]
    watch.sample("topic1", 1_600 * MS, 1_600 * MS)
    assert [(m.aside, m.time, m.reason) for m in moves[1:]] == [
        (False, 1_600 * MS, "a sample came after 0.6 s without one")
    ]
    never = QualityWatch(0, moves.append)
    never.declare(("t",), FeatureKey("X", ()), "p", "t", Fraction(10), None)
    never.sample("t", 0, 0)
    never.silent(10**12)
    assert len(moves) == 2 and never.aside() == []
    # a topic that never sends is silent from the start (`begin`), one matched later from
    # when it was; each is set aside past three periods
    mute = QualityWatch(3, moves.append)
    mute.declare(("a",), FeatureKey("X", ()), "p", "a", Fraction(10), None)
    mute.begin(1_000 * MS)
    mute.declare(("b",), FeatureKey("Y", ()), "p", "b", Fraction(10), None, since=2_000 * MS)
    assert mute.due == 1_300 * MS
    mute.silent(1_301 * MS)
    mute.silent(2_301 * MS)
    over = "0.301 s, over 3 periods of the declared 10 Hz"
    assert [(m.topic, m.time, m.reason) for m in moves[2:]] == [
        ("a", 1_301 * MS, f"no sample since the start ({over})"),
        ("b", 2_301 * MS, f"no sample since matched ({over})"),
    ]
    mute.sample("a", 1_500 * MS, 1_500 * MS)
    assert moves[-1].reason == "a sample came after 0.5 s without one"


def test_with_best_source_the_next_ranked_topic_is_read_while_the_best_one_is_set_aside(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Under --best-source uav1's altitude is read from topic1 alone, yet topic2, ranked
    next, is read too (feeding nothing): when topic1 stops, the altitude is read from
    topic2 until topic1 sends again, at the same stream times as the merge's changes."""
    config, path = declare(scenario, *TEN_HZ), stalled(tmp_path)
    km = KnowledgeManager.from_config(config)
    request = km.check_formula(ALTITUDE, best_source=True)
    assert topics(request.features) == ["topic1"]
    assert [t.topic for t in request.features[0].standby] == ["topic2"]
    events = replayed(km, path, best_source=True)
    moves = [e for e in events if isinstance(e, Rerouted)]
    one, two = ("platform1/topic1",), ("platform1/topic2",)
    assert [(m.source, m.aside, m.before, m.after) for m in moves] == [
        ("platform1/topic1", True, one, two),
        ("platform1/topic1", False, two, one),
    ]
    merged = [e for e in replayed(km, path) if isinstance(e, Rerouted)]
    assert [(m.time, m.t, m.reason) for m in moves] == [(m.time, m.t, m.reason) for m in merged]
    (verdict,) = [e for e in events if isinstance(e, Verdict)]
    assert verdict.verdict is True
    argv = ["monitor", "--config", str(config), "--source", str(path), "--best-source"]
    assert main([*argv, "--json", ALTITUDE]) == 0
    shown = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(m["change"], m["before"], m["after"]) for m in shown if "rerouted" in m] == [
        ("set_aside", list(one), list(two)),
        ("taken_back", list(two), list(one)),
    ]


def test_explain_under_best_source_says_which_topic_is_chosen_and_why_another_stands_by(
    scenario: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = declare(scenario, SLOW, LAGGING)
    km = KnowledgeManager.from_config(config)
    why = {w.topic: w.summary for w in km.explain(ALTITUDE, best_source=True).features[0].why}
    assert why["topic2"][-1] == "chosen (--best-source): ranked first"
    assert why["topic1"][-1] == (
        "standing by (--best-source): ranked after platform1/topic2 (age 1.02s > age "
        "220ms); read, and re-routed to if that one is set aside"
    )
    assert not any(
        "best-source" in line for w in km.explain(ALTITUDE).features[0].why for line in w.summary
    )
    # with --max-delay topic2 is excluded: topic1, the only one left, is chosen
    (only,) = km.explain(ALTITUDE, max_delay="100ms", best_source=True).features[0].why
    assert (only.topic, only.summary[-1]) == ("topic1", "chosen (--best-source): ranked first")
    assert main(["explain", "--config", str(config), "--best-source", ALTITUDE]) == 0
    assert "standing by (--best-source): ranked after platform1/topic2" in capsys.readouterr().out
    # a topic named that feeds another feature only: nothing to rank
    speed = km.explain("always (Speed[car1] > 1)", topic="topic1", best_source=True)
    assert not speed.features[0].why and speed.features[0].why_not


def test_a_batch_run_under_best_source_is_re_routed_as_monitor_does(
    scenario: Path, tmp_path: Path
) -> None:
    """topic2 says uav1 flies at 5 m: once topic1 (the best) is set aside, the altitude is
    read from topic2 and the formula fails, in a batch worker (no knowledge base to match
    again) as in `monitor`."""
    from dkreason.batch import Job, Run, monitor_run

    km = KnowledgeManager.from_config(declare(scenario, *TEN_HZ))
    rows: list[Row] = [("topic2", UAV, n * 100 * MS, {"id": 1, "alt": 5.0}) for n in range(1, 61)]
    rows += [
        ("topic1", UAV, n * 100 * MS + 50 * MS, {"id": 1, "alt": 50.0})
        for n in range(1, 60)
        if not 20 <= n < 40
    ]
    path = tmp_path / "low.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    formula, policy = "always (Altitude[uav1] > 10)", StreamPolicy(best_source=True)
    with km.monitor(formula, [path], policy) as run:
        (alone,) = [e for e in run if isinstance(e, Verdict)]
    # set aside at 2.3 s (t+2.2) by topic2's sample then, 0.35 s after topic1's last: that
    # sample, held while topic2 stood by, is the first read from it
    assert (alone.verdict, alone.t) == (False, 2.2)
    plan = km.plan(formula)
    job = Job(
        plan, km.matcher(policy)(plan), policy, tuple(km.platforms), (), "auto", (), None, None
    )
    ((_, verdict),) = monitor_run(job, Run("low", (str(path),))).verdicts
    assert verdict is not None and (verdict.verdict, verdict.t) == (False, 2.2)


def test_under_best_source_nothing_stands_by_a_topic_that_declares_no_rate(scenario: Path) -> None:
    """topic2, chosen, declares no rate: it is never set aside, so topic1 is not read."""
    km = KnowledgeManager.from_config(declare(scenario, "topic2:UavMsg [delay 10ms]"))
    (feature,) = km.check_formula(ALTITUDE, best_source=True).features
    assert [t.topic for t in feature.topics] == ["topic2"] and not feature.standby
    why = {w.topic: w.summary for w in km.explain(ALTITUDE, best_source=True).features[0].why}
    assert why["topic1"][-1] == (
        "not chosen (--best-source): ranked after platform1/topic2 (no declared age > age 10ms)"
    )
    thesis = KnowledgeManager.from_config(SCENARIOS / "federation.toml")  # declaring nothing
    formula = "always (Altitude[uav1] > Altitude[uav2])"
    assert not any(f.standby for f in thesis.check_formula(formula, best_source=True).features)


def topic2_alone(tmp_path: Path) -> Path:
    """uav1's altitude on topic2 alone, at 10 Hz for 2 s: topic1 is in no recording."""
    rows: list[Row] = [("topic2", UAV, n * 100 * MS, {"id": 1, "alt": 50.0}) for n in range(1, 21)]
    path = tmp_path / "alone.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    return path


@pytest.mark.parametrize(
    ("best_source", "before"),
    [(True, ("platform1/topic1",)), (False, ("platform1/topic1", "platform1/topic2"))],
    ids=["best-source", "merged"],
)
def test_a_topic_that_never_sends_is_set_aside_counting_from_the_start(
    scenario: Path, tmp_path: Path, best_source: bool, before: tuple[str, ...]
) -> None:
    """topic1 (declared 10 Hz, chosen under --best-source) sends nothing: its silence counts
    from the start of the recording (0.1 s), so past three periods (at topic2's message of
    0.5 s) it is set aside, once, and uav1's altitude is read from topic2."""
    km = KnowledgeManager.from_config(declare(scenario, *TEN_HZ))
    events = replayed(km, topic2_alone(tmp_path), best_source=best_source)
    (move,) = [e for e in events if isinstance(e, Rerouted)]
    assert (move.source, move.aside, move.before, move.after) == (
        "platform1/topic1",
        True,
        before,
        ("platform1/topic2",),
    )
    assert (move.time, move.t) == (0.5, 0.4)
    assert move.reason == (
        "no sample since the start (0.4 s, over 3 periods of the declared 10 Hz)"
    )
    (verdict,) = [e for e in events if isinstance(e, Verdict)]
    assert verdict.verdict is True


def test_monitor_says_once_that_a_best_topic_never_sent(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config, path = declare(scenario, *TEN_HZ), topic2_alone(tmp_path)
    argv = ["monitor", "--config", str(config), "--source", str(path), "--best-source"]
    assert main([*argv, ALTITUDE]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "rerouted" in line]
    assert len(lines) == 1 and "no sample since the start" in lines[0]


def test_at_a_switch_the_topic_standing_by_gives_its_newest_sample_at_once(
    scenario: Path, tmp_path: Path
) -> None:
    """With a 150 ms maximum age topic1's last altitude (1.95 s) is unknown from 2.1 s on;
    at 2.3 s topic2's message shows topic1 silent for over three periods: that message,
    read while topic2 stood by, gives the altitude its value at once, at its valid time,
    and it is known from then on."""
    km = KnowledgeManager.from_config(declare(scenario, *TEN_HZ))
    policy = StreamPolicy(best_source=True, max_age=Fraction(3, 20))
    key = km.check_formula(ALTITUDE).features[0].feature.key
    with km.monitor(ALTITUDE, [stalled(tmp_path)], policy, keep_states=True) as run:
        events = list(run)
    states = run.states
    (aside, _) = [e for e in events if isinstance(e, Rerouted)]
    assert aside.time == 2.3
    switch = int(aside.time * 10**9)
    after = [(t, values[key]) for t, values in states if t >= switch]
    assert after[0] == (switch, 50.0)  # the sample that revealed the silence
    assert all(v is not None for _, v in after)


def test_a_held_sample_older_than_the_last_state_feeds_at_the_switch(
    scenario: Path, tmp_path: Path
) -> None:
    """topic2 (1 Hz, standing by) last said 40 m at 2.0 s; car1's speed makes a state every
    100 ms.  topic1 (10 Hz, chosen) stops after 1.95 s; car1's message at 2.32 s shows it:
    by then the state at 2.22 s was made, so topic2's 40 m is fed at the switch (2.32 s),
    not as a late sample at 2.0 s."""
    km = KnowledgeManager.from_config(
        declare(scenario, "topic1:UavMsg [rate 10 Hz]", "topic2:UavMsg [rate 1 Hz]")
    )
    rows: list[Row] = [
        ("topic3", CAR, n * 100 * MS + 20 * MS, {"id": 1, "spd": 3.0}) for n in range(1, 40)
    ]
    rows += [("topic1", UAV, n * 100 * MS + 50 * MS, {"id": 1, "alt": 50.0}) for n in range(1, 20)]
    rows += [("topic2", UAV, n * 1000 * MS, {"id": 1, "alt": 40.0}) for n in range(1, 4)]
    path = tmp_path / "held.mcap"
    write_recording(path, "bare-mcap", TYPES, rows)
    formula = "always (Altitude[uav1] > 1 and Speed[car1] >= 0)"
    request = km.check_formula(formula, best_source=True)
    altitude = next(f.feature.key for f in request.features if f.feature.name == "Altitude")
    policy = StreamPolicy(best_source=True)
    with km.monitor(formula, [path], policy, keep_states=True) as run:
        events = list(run)
    (aside,) = [e for e in events if isinstance(e, Rerouted)]
    assert aside.time == 2.32
    assert not [e for e in events if isinstance(e, Violation) and e.constraint == "late"]
    assert [(t, v[altitude]) for t, v in run.states if 2_200 * MS < t <= 2_320 * MS] == [
        (2_220 * MS, 50.0),
        (2_320 * MS, 40.0),
    ]
