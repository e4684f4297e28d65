"""Make the bundled ``sample_logs/`` with the simulator and record the truth beside them.

Run from the repository root: ``python scripts/make_sample_logs.py`` (replaces the files).
"""

from __future__ import annotations

import json
from pathlib import Path

from balancer_id.fit import resolve_model
from balancer_id.simulate.inputs import parse_trajectory
from balancer_id.simulate.synth import SensorSettings, write_synthetic_log

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "sample_logs"
HOSE = ROOT / "examples" / "effects" / "hose_spring.py"
PAPER = {"m_a": 15.1, "T_a": 0.33, "D0": 6.0, "A": 0.4}
THRUSTS = [2.45, -2.45, 4.9, -4.9, 7.35, -7.35]

#: The robot-assist move of the human/robot pair (paper section IV): 200 mm up.
MOVE = "trapezoid:distance=0.2,speed=0.1,accel=0.5,start=2.0"

SAMPLES = [
    {
        "file": "paper_balancer.csv",
        "about": "the paper's balancer: variable viscosity, six step trials, tilted sensor",
        "model": "variable_viscosity",
        "params": PAPER,
        "thrusts": THRUSTS,
        "sensor": {
            "tilt_deg": 12.0,
            "accel_noise": 0.03,
            "force_noise": 0.03,
            "drop_fraction": 0.005,
        },
        "seed": 1,
    },
    {
        "file": "quantized_sensor.csv",
        "about": "the same balancer seen at the sensor's resolution (0.2 m/s^2, 0.03 N)",
        "model": "variable_viscosity",
        "params": PAPER,
        "thrusts": THRUSTS,
        "sensor": {"tilt_deg": 20.0, "accel_noise": 0.08, "force_noise": 0.03, "quantize": True},
        "seed": 2,
    },
    {
        "file": "hose_walkthrough.csv",
        "about": "a balancer with a hose pulling the load back (not built in: README walk-through)",
        "model": "variable_viscosity+hose_spring",
        "effects_file": "examples/effects/hose_spring.py",
        "params": {**PAPER, "k_h": 4.0},
        "thrusts": THRUSTS,
        "sensor": {"tilt_deg": 8.0, "accel_noise": 0.03, "force_noise": 0.03},
        "seed": 3,
    },
    {
        "file": "robot/human_assist.csv",
        "about": "a person guides the load through the 200 mm move: a soft, well damped "
        "'servo' (the person's arm impedance) tracking the same reference as the robot",
        "model": "variable_viscosity+servo",
        "params": {**PAPER, "k_r": 30.0, "c_r": 35.0},
        "thrusts": [0.0],
        "trajectory": MOVE,
        "duration_s": 10.0,
        "sensor": {"tilt_deg": 12.0, "accel_noise": 0.03, "force_noise": 0.03},
        "seed": 4,
    },
    {
        "file": "robot/robot_assist.csv",
        "about": "a position-controlled robot makes the same 200 mm move through its servo "
        "(stiff, lightly damped): the coupled mode vibrates",
        "model": "variable_viscosity+servo",
        "params": {**PAPER, "k_r": 150.0, "c_r": 100.0},
        "thrusts": [0.0],
        "trajectory": MOVE,
        "duration_s": 10.0,
        "sensor": {"tilt_deg": 12.0, "accel_noise": 0.03, "force_noise": 0.03},
        "seed": 5,
    },
]


def main() -> None:
    """Write every sample log and ``TRUTH.json``."""
    OUT.mkdir(exist_ok=True)
    for sample in SAMPLES:
        files = [ROOT / sample["effects_file"]] if "effects_file" in sample else []
        model = resolve_model(sample["model"], files)
        (OUT / sample["file"]).parent.mkdir(exist_ok=True)
        write_synthetic_log(
            OUT / sample["file"],
            model,
            sample["params"],
            sample["thrusts"],
            sensor=SensorSettings(**sample["sensor"]),
            trajectory=parse_trajectory(sample["trajectory"]) if "trajectory" in sample else None,
            duration_s=sample.get("duration_s", 8.0),
            seed=sample["seed"],
            overwrite=True,
        )
        print(f"wrote {OUT / sample['file']}")
    (OUT / "TRUTH.json").write_text(json.dumps(SAMPLES, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
