# Two commands for a fresh machine: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export JAX_COMPILATION_CACHE_DIR ?= $(CURDIR)/.jax_cache
export MPLBACKEND ?= Agg

# tcmalloc, when installed, for every target (docs/performance.md: under glibc's malloc XLA's
# CPU temporaries cost ~1.5 GB of page faults per MeshGraphNet training step). The `thrombojax`
# command preloads it by itself; this covers the scripts and tests make runs. Opt out:
# THROMBOJAX_NO_TCMALLOC=1. The set-up installs it where it can (root with apt), else skips.
TCMALLOC_LIBS := $(foreach d,/usr/lib/x86_64-linux-gnu /usr/lib/aarch64-linux-gnu /usr/lib64 \
	/usr/lib /usr/local/lib,$(d)/libtcmalloc_minimal.so.4)
TCMALLOC := $(firstword $(wildcard $(TCMALLOC_LIBS)))
ifneq ($(TCMALLOC),)
ifneq ($(THROMBOJAX_NO_TCMALLOC),1)
ifeq ($(findstring tcmalloc,$(LD_PRELOAD)),)
export LD_PRELOAD := $(TCMALLOC)$(if $(LD_PRELOAD),:$(LD_PRELOAD))
endif
endif
endif

.PHONY: demo test lint venv clean tcmalloc

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test,experiments]'
	-@$(MAKE) --no-print-directory tcmalloc
	touch $(STAMP)

# Best effort, never fails: only as root with apt-get, and only when not installed yet.
tcmalloc:
	@if [ -z "$(TCMALLOC)" ] && [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		apt-get install -y -q libtcmalloc-minimal4 >/dev/null 2>&1 \
		&& echo "installed libtcmalloc-minimal4 (used from the next make command on)" \
		|| echo "could not install libtcmalloc-minimal4; continuing without it"; \
	fi; true

venv: $(STAMP)

demo: $(STAMP)
	$(BIN)/python experiments/demo.py --out demo_output

test: $(STAMP)
	$(BIN)/ruff check thrombojax tests benchmarks experiments
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder --durations=30

lint: $(STAMP)
	$(BIN)/ruff check thrombojax tests benchmarks experiments

clean:
	rm -rf $(VENV) .jax_cache demo_output .pytest_cache
