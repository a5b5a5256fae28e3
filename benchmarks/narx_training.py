"""Cost and outcome of the seed 002 NARX estimator (ANNC) built the way the paper describes.

Issue 28. Plant ``hybrid_three_tank``, ts = 1 s, only h3 measured (R = 2.5e-7 m^2, the
comparison's declared noise), EKF Q = 1e-9 I, P0 = 1e-2 I. Training data: the EKF run on the
simulated plant under the ``designed`` excitation (set-point steps of both pumps' levels in
[0.15, 0.50] m, i.e. both threshold modes of the middle pipes at h0 = 0.30 m, each held
60-200 samples by its equilibrium input, plus a three-level PRBS of +-20 lph on each pump),
6 training + 2 validation runs of 1500 samples; Levenberg-Marquardt on J'J + mu I with
validation early stopping (6 failures), at most 200 trial steps per restart (no wall-clock cap: a
time cap would make the fit depend on the machine), 2
restarts. The structure (hidden 3/5/8, output delays 1/2) is chosen by the closed-loop ISE
of the inverse-dynamics loop on held-out scenarios (servo and regulatory, seed 101).

Recorded (``benchmarks/results/narx_training.json``): training time and LM iterations of every
structure, the selection ISE, and the Tables 4-8 metrics of PERFECT (true state fed back),
EKFC, ANNC (the selected NARX, trained on EKF estimates) and ANNC_TRUE (the same NARX trained on
the true states: the controlled experiment). No floor: this records cost, it races nothing.

Usage::

    .venv/bin/python benchmarks/narx_training.py
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import machine, write_record  # noqa: E402

from tanksynth.comparison import (FilterTuning, comparison_estimators,  # noqa: E402
                                  controller_comparison, select_narx_structure,
                                  train_comparison_narx)
from tanksynth.papers.seed002 import TABLES  # noqa: E402
from tanksynth.plants import hybrid_three_tank  # noqa: E402
from tanksynth.plants.hybrid_three_tank import LPH  # noqa: E402

X_OP = (0.31918677, 0.3209075, 0.30968861)
GAINS = (0.05, 0.05)
TUNING = FilterTuning(Q=1e-9, R=2.5e-7, P0=1e-2, substeps=2, narx_runs=6, narx_steps=1500,
                      narx_restarts=2, narx_iterations=200, narx_excitation="designed",
                      narx_setpoint_range=(0.15, 0.50), narx_prbs_amplitude=20 * LPH,
                      narx_hold=(60, 200), narx_time_limit=None)


def main() -> int:
    before = machine()
    plant = hybrid_three_tank()
    t0 = time.perf_counter()
    chosen, candidates = select_narx_structure(plant, 1.0, X_OP, TUNING, gains=GAINS)
    selection_s = time.perf_counter() - t0
    for c in candidates:
        print(f"hidden {c.hidden} delays {c.delays}: held-out ISE {c.ise:.5f} m^2 s, "
              f"training {c.train_seconds:.1f} s, {c.iterations} LM steps")
    print(f"chosen hidden {chosen.narx_hidden}, delays {chosen.narx_delays} ({selection_s:.0f} s)")
    t0 = time.perf_counter()
    training = train_comparison_narx(plant, 1.0, X_OP, chosen)
    train_s = time.perf_counter() - t0
    true_tuning = dataclasses.replace(chosen, narx_target="true")
    est = comparison_estimators(plant, 1.0, {"PERFECT": None, "EKFC": "ekf", "UKFC": "ukf",
                                             "ANNC": "narx"}, chosen, X_OP)
    est_true = comparison_estimators(plant, 1.0, {"ANNC_TRUE": "narx"}, true_tuning, X_OP)
    rows = controller_comparison(plant, {**est, **est_true}, x_op=X_OP, gains=GAINS, ts=1.0,
                                 runs=2, scenarios=list(TABLES))
    table = {}
    for r in rows:
        table.setdefault(r.scenario, {})[r.controller] = dict(r.metrics)
        m = r.metrics
        print(f"{r.scenario:18s} {r.controller:9s} ISE {m['ise_h1']:.4f} {m['ise_h2']:.4f}  "
              f"RMSE h1 {m.get('rmse_h1', float('nan')):.4f}  offset {m['offset']:+.4f}")
    payload = {"tuning": dataclasses.asdict(TUNING), "gains": GAINS, "x_op": X_OP,
               "selection_seconds": selection_s,
               "candidates": [dataclasses.asdict(c) for c in candidates],
               "chosen": {"hidden": chosen.narx_hidden, "delays": chosen.narx_delays},
               "final_training_seconds": train_s,
               "final_training": training.diagnostics["training"] | {"candidates": None},
               "closed_loop_validation": training.diagnostics["closed_loop_validation"],
               "tables": table}
    print("wrote", write_record("narx_training", payload, before))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
