"""Two turtlesim robots under their namespaces, as `ros2 bag record /turtle1/pose
/turtle2/pose` would record them (a ROS 2 bag, MCAP storage), for the README's walk-through.

turtle1 drifts from the middle of its window towards the right edge and ends at x = 9.5019;
turtle2 sways around the middle.  Ten poses a second each for 20 s, from 2026-11-24 10:00 UTC.

    python examples/turtles/simulate.py examples/turtles/recording
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from dkreason.stream.recording import Row, write_recording

HERE = Path(__file__).parent
S = 10**9
START = 1_795_514_400 * S  # 2026-11-24T10:00:00Z
POSE = "turtlesim/msg/Pose"
TYPES = {
    POSE: "float32 x\nfloat32 y\nfloat32 theta\nfloat32 linear_velocity\nfloat32 angular_velocity\n"
}


def pose(x: float, theta: float) -> dict[str, float]:
    return {"x": x, "y": 5.5, "theta": theta, "linear_velocity": 0.2, "angular_velocity": 0.0}


def messages() -> list[Row]:
    out: list[Row] = []
    for k in range(200):
        t = k / 10
        out.append(("/turtle1/pose", POSE, START + k * S // 10, pose(5.5 + 4.0019 * k / 199, 0)))
        out.append(
            ("/turtle2/pose", POSE, START + k * S // 10 + S // 200, pose(5.5 + math.sin(t), 1.5))
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
