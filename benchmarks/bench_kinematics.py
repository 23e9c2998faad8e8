"""Benchmark: pose + pose Jacobian of the LBR4p, ours against DQ Robotics and Pinocchio.

Run::

    python benchmarks/bench_kinematics.py [--json PATH] [--repeat 9]

Prints the median wall time [µs] over ``--repeat`` ``timeit.repeat`` runs of:

* ``RobotModel._pose_and_jacobian(q)`` (unchecked hot path) and ``pose_and_jacobian(q)``;
* ``RobotModel.poses_and_jacobians(qs)`` for a batch of 10 configurations (the closed form
  of ``dqcontrol.model.chain_batch`` for the LBR4p), and the same batch by the Pinocchio
  loop every other model takes (checked input in both);
* if ``dqrobotics`` is importable: ``DQ_SerialManipulatorDH`` with the thesis's DH table,
  one ``fkm(q)`` + ``pose_jacobian(q)``, and ten of them (the same work as our batch);
* Pinocchio's bare ``computeFrameJacobian`` as a floor (the one C++ call ours wraps).

It first checks that DQ Robotics's fkm and pose Jacobian equal ours (vec8, sign-aligned), so
the comparison is between two computations of the same thing. Targets: single ≤ 1.0× DQR,
batch of 10 ≤ 0.5× ten DQR calls.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import timeit
from pathlib import Path

import numpy as np
import pinocchio as pin

import dqcontrol

BATCH = 10
#: The thesis's LBR4p (eq. 4.2–4.3), standard DH: rows theta, d, a, alpha, joint type.
DH_D = [0.2, 0.0, 0.4, 0.0, 0.39, 0.0, 0.078]
DH_ALPHA = [np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0]
BASE_Z_M = 0.51


def median_us(stmt, number: int, repeat: int) -> float:
    """Median over ``repeat`` runs of the mean time of one call of ``stmt`` [µs]."""
    times = timeit.repeat(stmt, number=number, repeat=repeat)
    return float(np.median(times)) / number * 1e6


def make_dqrobotics_lbr4p():
    """DQ Robotics's LBR4p, or ``None`` if dqrobotics is not installed."""
    try:
        from dqrobotics import E_, k_
        from dqrobotics.robot_modeling import DQ_SerialManipulatorDH
    except ImportError:
        return None
    n = len(DH_D)
    dh_matrix = np.array(
        [np.zeros(n), DH_D, np.zeros(n), DH_ALPHA, np.zeros(n)]  # type 0 = revolute
    )
    robot = DQ_SerialManipulatorDH(dh_matrix)  # dqrobotics ≥ 20.04: 5 × n matrix
    base = 1 + 0.5 * E_ * BASE_Z_M * k_
    robot.set_base_frame(base)
    # In dqrobotics 26.x fkm() composes the *reference* frame (base_frame is only stored),
    # so the same pose must be set as the reference frame as well to get the thesis's chain.
    robot.set_reference_frame(base)
    return robot


def check_same_kinematics(model: dqcontrol.RobotModel, robot, qs: np.ndarray) -> float:
    """Largest difference between DQ Robotics's and our vec8 pose / pose Jacobian."""
    from dqrobotics import vec8

    worst = 0.0
    for q in qs:
        x, jac = model.pose_and_jacobian(q)
        x_dqr = vec8(robot.fkm(q))
        j_dqr = np.asarray(robot.pose_jacobian(q))
        sign = 1.0 if np.dot(x, x_dqr) >= 0.0 else -1.0
        worst = max(worst, np.abs(sign * x_dqr - x).max(), np.abs(sign * j_dqr - jac).max())
    return worst


def run(repeat: int) -> dict:
    model = dqcontrol.load_lbr4p()
    rng = np.random.default_rng(12345)
    qs = rng.uniform(model.limits.q_min, model.limits.q_max, size=(BATCH, model.nq))
    q = qs[0]
    fid = model.model.getFrameId(model.ee_frame)
    pmodel, pdata = model.model, model.data
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    number = 2000
    results: dict = {
        "python": platform.python_version(),
        "pinocchio": pin.__version__,
        "numpy": np.__version__,
        "repeat": repeat,
        "us": {},
    }
    us = results["us"]
    us["ours_single_unchecked"] = median_us(lambda: model._pose_and_jacobian(q), number, repeat)
    us["ours_single_public"] = median_us(lambda: model.pose_and_jacobian(q), number, repeat)
    us["ours_batch10"] = median_us(lambda: model.poses_and_jacobians(qs), number // 10, repeat)
    results["batch_path"] = "pinocchio loop" if model._chain is None else "closed form"
    check, loop = model.check_batch, model._poses_and_jacobians_pinocchio
    us["ours_batch10_pinocchio_loop"] = median_us(lambda: loop(check(qs)), number // 10, repeat)
    us["pinocchio_frame_jacobian_floor"] = median_us(
        lambda: pin.computeFrameJacobian(pmodel, pdata, q, fid, lwa), number, repeat
    )

    robot = make_dqrobotics_lbr4p()
    if robot is not None:
        import dqrobotics

        results["dqrobotics"] = getattr(dqrobotics, "__version__", "unknown")
        difference = check_same_kinematics(model, robot, model.random_configurations(200, 7))
        results["max_difference_vs_dqrobotics"] = difference
        if difference > 1e-12:
            raise SystemExit(
                f"DQ Robotics and dqcontrol disagree by {difference:.3g}: not a fair comparison"
            )
        fkm, jac = robot.fkm, robot.pose_jacobian

        def dqr_single():
            fkm(q)
            jac(q)

        def dqr_ten():
            for qi in qs:
                fkm(qi)
                jac(qi)

        us["dqr_single"] = median_us(dqr_single, number, repeat)
        us["dqr_ten"] = median_us(dqr_ten, number // 10, repeat)
        results["ratios"] = {
            "single_unchecked_vs_dqr": us["ours_single_unchecked"] / us["dqr_single"],
            "single_public_vs_dqr": us["ours_single_public"] / us["dqr_single"],
            "batch10_vs_dqr_ten": us["ours_batch10"] / us["dqr_ten"],
            "batch10_pinocchio_loop_vs_dqr_ten": us["ours_batch10_pinocchio_loop"] / us["dqr_ten"],
        }
    return results


def report(results: dict) -> None:
    us = results["us"]
    print(f"LBR4p pose + pose Jacobian, median of {results['repeat']} runs [µs per call]")
    print(f"  ours  _pose_and_jacobian (unchecked) {us['ours_single_unchecked']:8.2f}")
    print(f"  ours  pose_and_jacobian (public)     {us['ours_single_public']:8.2f}")
    batch, path = us["ours_batch10"], results["batch_path"]
    print(f"  ours  poses_and_jacobians, N = {BATCH}    {batch:8.2f}  ({path})")
    print(f"  ours  same batch, Pinocchio loop     {us['ours_batch10_pinocchio_loop']:8.2f}")
    print(f"  pin   computeFrameJacobian (floor)   {us['pinocchio_frame_jacobian_floor']:8.2f}")
    if "dqr_single" not in us:
        print("  dqrobotics not importable: no comparison")
        return
    r = results["ratios"]
    print(f"  DQR   fkm + pose_jacobian            {us['dqr_single']:8.2f}")
    print(f"  DQR   10 × (fkm + pose_jacobian)     {us['dqr_ten']:8.2f}")
    print(
        f"  (DQ Robotics {results['dqrobotics']}: same kinematics to "
        f"{results['max_difference_vs_dqrobotics']:.1e})"
    )
    print("ratios ours / DQR")
    print(f"  single, unchecked   {r['single_unchecked_vs_dqr']:.2f}×  (target ≤ 1.0×)")
    print(f"  single, public      {r['single_public_vs_dqr']:.2f}×  (target ≤ 1.0×)")
    print(f"  batch of {BATCH} vs ten  {r['batch10_vs_dqr_ten']:.2f}×  (target ≤ 0.5×)")
    print(f"  (Pinocchio loop      {r['batch10_pinocchio_loop_vs_dqr_ten']:.2f}×)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", type=Path, help="write the figures to this JSON file")
    parser.add_argument("--repeat", type=int, default=9, help="timeit repeats (≥ 7)")
    args = parser.parse_args(argv)
    if args.repeat < 7:
        parser.error("--repeat must be ≥ 7")
    results = run(args.repeat)
    report(results)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
