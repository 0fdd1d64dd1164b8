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
if "xla_backend_optimization_level" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_backend_optimization_level=1").strip()

import jax  # noqa: E402

jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
jax.config.update("jax_persistent_cache_min_compile_time_secs",
                  float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))
