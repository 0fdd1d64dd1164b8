# The device scripts' set-up, sourced from the repository root (`. experiments/results/ladder_gpu/device_env.sh`):
# installs the wheels the device image lacks (jraph, meshio: carried in .whl/) into /tmp/site
# when .whl/ is there, and sets the environment every device job runs with. Returns non-zero
# when the install fails.
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || return 1
fi
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1 MPLBACKEND=Agg \
    XLA_PYTHON_CLIENT_PREALLOCATE=false JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
