"""Time one epoch's validation rollout (``thrombojax.train.validation``) of a trained run.

Usage: ``python time_val_rollout.py RUN DATASET`` (here the current dirspeed seed 0 run).
"""

import os
import sys
import time

from thrombojax.io.hdf5 import open_dataset
from thrombojax.train.state import load_trained
from thrombojax.train.validation import prepare_val_rollouts, val_rollout_metrics

run, data = sys.argv[1], sys.argv[2]
trained = load_trained(run)
ds = open_dataset(data)
t0 = time.perf_counter()
sims = prepare_val_rollouts(ds, trained.split.val, trained.scaling, trained.step)
t1 = time.perf_counter()
val_rollout_metrics(trained.params, trained.stats, sims, 1.0)  # compiles
t2 = time.perf_counter()
times = []
for _ in range(3):
    start = time.perf_counter()
    print(val_rollout_metrics(trained.params, trained.stats, sims, 1.0))
    times.append(time.perf_counter() - start)
print(f"prepare {t1 - t0:.2f} s, first (compile) {t2 - t1:.2f} s, then {min(times):.2f}-"
      f"{max(times):.2f} s; load {os.getloadavg()}")
