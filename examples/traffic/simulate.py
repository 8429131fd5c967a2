"""The thesis' motivating scenario (1.2, 4.4): three platforms watch a road; write what they
recorded as one ROS 2 bag (MCAP storage) with the custom types CarMsg, UavMsg, AutomobileMsg and
UasMsg of the bundled topic specifications.

car2 drives at 70 km/h for 200 s in platform 1's region, then 150 s more in platform 2's region,
where platform 2 sees it as car12 (`car2 same car12`): only platform 2's carstopic1 shows that
the speeding went on for more than 300 s.  car1 and car3 stay in platform 1's region and keep to
the limit (car3 drops back within 300 s).  Platform 2 also tracks car12's position along the
road all the time (carstopic3, its only source).  Platform 3's UAS report their speed and
height, and uastopic9 carries uas21's height though no topic specification describes it yet
(the live example adds one while running).

    python examples/traffic/simulate.py examples/traffic/recording
"""

from __future__ import annotations

import sys
from pathlib import Path

from dkreason.stream.recording import write_recording

HERE = Path(__file__).parent
S = 10**9
TYPES = {
    f"dkreason_msgs/msg/{p.stem}": p.read_text(encoding="utf-8")
    for p in sorted((HERE / "msg" / "dkreason_msgs" / "msg").glob("*.msg"))
}
DURATION = 360  # seconds recorded
ENTERS_P2 = 200  # car2 leaves platform 1's region for platform 2's
LEAVES_P2 = 350


def speeds(t: int) -> dict[str, float]:
    """km/h of each car at second t."""
    return {"car1": 50.0 + (t % 7) * 0.5, "car2": 70.0, "car3": 65.0 if t < 100 else 52.0}


def messages() -> list[tuple[str, str, int, dict[str, object]]]:
    out: list[tuple[str, str, int, dict[str, object]]] = []
    car, uav = "dkreason_msgs/msg/CarMsg", "dkreason_msgs/msg/UavMsg"
    auto, uas = "dkreason_msgs/msg/AutomobileMsg", "dkreason_msgs/msg/UasMsg"
    for t in range(DURATION):
        v = speeds(t)
        # platform 1: one topic per car while it is in platform 1's region, and the UAVs
        out.append(("/platform1/topic3", car, t * S, {"id": 1, "spd": v["car1"]}))
        if t < ENTERS_P2:
            out.append(("/platform1/topic4", car, t * S + 10_000_000, {"id": 2, "spd": v["car2"]}))
        out.append(("/platform1/topic5", car, t * S + 20_000_000, {"id": 3, "spd": v["car3"]}))
        for n in (1, 2):
            out.append(
                (
                    "/platform1/topic2",
                    uav,
                    t * S + 30_000_000 + n,
                    {"id": n, "alt": 100.0 + 10 * n + t % 5, "spd": 40.0},
                )
            )
        # platform 2: cars in its region, stamped when measured, recorded 50 ms later
        if ENTERS_P2 <= t < LEAVES_P2:
            out.append(
                (
                    "/platform2/carstopic1",
                    auto,
                    t * S + 50_000_000,
                    {"header": {"stamp": t}, "id": 12, "speed": v["car2"]},
                )
            )
        out.append(
            (
                "/platform2/carstopic3",
                auto,
                t * S + 55_000_000,
                {
                    "header": {"stamp": t},
                    "id": 12,
                    "speed": v["car2"],
                    "position": round(t * v["car2"] / 3.6, 1),
                },
            )
        )
        # platform 3: its unmanned aircraft systems
        out.append(
            (
                "/platform3/uastopic9",
                uas,
                t * S + 70_000_000,
                {"header": {"stamp": t}, "id": 21, "speed": 38.0, "height": 95.0},
            )
        )
        for n in (20, 21):
            out.append(
                (
                    "/platform3/uastopic1",
                    uas,
                    t * S + 60_000_000 + n,
                    {"header": {"stamp": t}, "id": n, "speed": 38.0, "height": 120.0},
                )
            )
    return out


def main() -> None:
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "recording"
    if target.exists():
        print(f"{target} exists; remove it to record again")
        return
    rows = messages()
    write_recording(target, "mcap", TYPES, rows)
    print(f"wrote {target} ({len(rows)} messages)")


if __name__ == "__main__":
    main()
