"""Test configuration: CPU only, headless plots, compilation cache, strict-ish numerics."""

import os
import pathlib

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("JAX_PLATFORMS", "cpu")
_cache = pathlib.Path(__file__).resolve().parent.parent / ".jax_cache"
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(_cache))
# cache every compilation, also the sub-second ones, here and in the commands tests start as
# subprocesses (they inherit the environment): the tiny models' programs recur across tests,
# and a warm `thrombojax train` of the kill trials takes ~20 % less than with jax's 1 s default
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
# LLVM at -O1 instead of -O2 for the CPU backend, unless XLA_FLAGS already chooses a level: the
# suite's time is mostly compiling small programs (measured: test_mgn_fast 52 -> 38 s,
# test_train_step 109 -> 99 s, four mixed files 231 -> 218 s); -O0 makes the training tests
# slower (test_train_step 145 s). Results stay within the tests' tolerances.
# XLA's older CPU emitters instead of its fusion emitters, unless XLA_FLAGS already chooses: they
# compile the suite's small programs faster (measured on a 2-core AMD EPYC, cold cache, CPU
# time: tests/test_flat_batch.py -k loss_and_gradients 51-55 -> 34-41 s, tests/test_train_step.py
# 121 -> 107 s wall). Both are XLA's supported CPU code paths; results stay within tolerances.
_TEST_XLA_FLAGS = {"xla_backend_optimization_level": "1", "xla_cpu_use_fusion_emitters": "false"}
for _flag, _value in _TEST_XLA_FLAGS.items():
    if _flag not in os.environ.get("XLA_FLAGS", ""):
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                                   + f" --{_flag}={_value}").strip()

import jax  # noqa: E402

jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
jax.config.update("jax_persistent_cache_min_compile_time_secs",
                  float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))


def pytest_collection_modifyitems(config, items):
    """Run the longest files first: those marked ``slow_safety`` (the kill -9 trials, one test
    of 25-120 s each), then those marked ``slow`` (a minute or more), then the rest, each file
    whole and in its own order. With ``-n 2 --dist loadfile --no-loadscope-reorder`` (`make
    test`) the two workers then end on short files together; xdist's default order (most tests
    first) left a one-test kill-trial file of about 100 s to one worker at the end."""
    def rank(item) -> int:
        return (0 if item.get_closest_marker("slow_safety")
                else 1 if item.get_closest_marker("slow") else 2)

    file_rank: dict[str, int] = {}
    for item in items:
        key = str(item.path)
        file_rank[key] = min(file_rank.get(key, 2), rank(item))
    items.sort(key=lambda item: file_rank[str(item.path)])  # stable: files stay whole
