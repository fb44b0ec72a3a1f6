"""``cmanip bench timestep``: how the plant's time step trades accuracy for speed.

Runs the demo push (empty scene, box, 0.3 m at 5 cm/s) at several discrete time steps and
reports, per step, the median real-time factor over ``repeats`` runs, the box's final
pose difference from the smallest step (position mm, orientation deg) and the RMS
difference of the tactile patch forces from the smallest step's (N, same noise draws).
The smallest step is the baseline of the accuracy columns; the speed column is a ratio
against its speed.
This is the measurement behind :data:`models.contact.DEFAULT_TIME_STEP_S`.
"""

from __future__ import annotations

import numpy as np

from diagrams.herb.straight_push import run_straight_push
from models.contact import SimulationConfig
from models.herb.scene import SceneSpec
from models.herb.tactile import TactileLayout
from models.pose import wrap_angle


def run_timestep_bench(steps_s: list[float], *, repeats: int = 3,
                       push_distance_m: float = 0.3) -> dict:
    """Measure each time step; print a table and return it as a dict (JSON-ready)."""
    scene = SceneSpec.load("empty")
    layout = TactileLayout.load("default")
    rows = []
    for step in sorted(steps_s):
        runs = [run_straight_push(scene, push_distance_m, layout=layout,
                                  sim=SimulationConfig(time_step_s=step), progress=False)
                for _ in range(repeats)]
        rows.append({
            "time_step_s": step,
            "real_time_factor_median": float(np.median(
                [r.summary["real_time_factor"] for r in runs])),
            "object_final_pose": runs[0].summary["object_final_pose"],
            "object_displacement_m": runs[0].summary["object_displacement_m"],
            "patch_force_n": runs[0].force_n,
        })
    reference = np.array(rows[0]["object_final_pose"])
    reference_force = rows[0]["patch_force_n"]
    base_speed = rows[0]["real_time_factor_median"]
    print(f"{'step (ms)':>9} {'RTF median':>10} {'x baseline':>10} {'dpos (mm)':>10} "
          f"{'dtheta (deg)':>12} {'force rmse (N)':>14} {'moved (m)':>9}")
    for row in rows:
        pose = np.array(row["object_final_pose"])
        row["position_error_mm"] = float(1000 * np.linalg.norm(pose[:2] - reference[:2]))
        row["orientation_error_deg"] = float(np.rad2deg(abs(wrap_angle(pose[2] - reference[2]))))
        row["speedup_vs_smallest_step"] = row["real_time_factor_median"] / base_speed
        force = row.pop("patch_force_n")
        samples = min(len(force), len(reference_force))
        row["patch_force_rmse_n"] = float(np.sqrt(np.mean(
            (force[:samples] - reference_force[:samples]) ** 2)))
        print(f"{1000 * row['time_step_s']:9.1f} {row['real_time_factor_median']:10.2f} "
              f"{row['speedup_vs_smallest_step']:10.2f} {row['position_error_mm']:10.1f} "
              f"{row['orientation_error_deg']:12.2f} {row['patch_force_rmse_n']:14.3f} "
              f"{row['object_displacement_m']:9.3f}")
    return {"scene": "empty", "object": "box", "push_distance_m": push_distance_m,
            "repeats": repeats, "rows": rows}
