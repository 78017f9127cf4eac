#!/usr/bin/env bash
# Run ON THE DEVICE (the GPU machine of the device tool), in the repository root, as one
# call: run(command="bash benchmarks/gpu/figures.sh", carry=[".whl"], timeout_s=590),
# after `bash benchmarks/gpu/wheels.sh` here. Issue 23's GPU figures in one go: the
# closed loop of each robot on MJX at large batches (`benchmarks/bench_sim.py --robots`),
# the first call (trace, compile, one rollout) beside each, into $OUT (env.txt,
# <robot>.txt). The image's python3 (3.12, jax 0.11.2 with CUDA) gets the wheels in
# /tmp/site; nothing is installed into it. Batch sizes and horizon from the environment:
#   LEGGROPE_BATCHES (default "1024 8192 65536"; the issue's goal: >= 1M closed-loop
#   physics steps/s for the leg-grope walk), OTHER_BATCHES ("8192"), ROBOTS ("snake
#   octopus titan"), HORIZON (1.0 simulated s per rollout), STEP_TIMEOUT (240 s per robot).
# Each robot runs in its own process under `timeout`, so one that runs long or fails
# leaves the others' figures; its exit status is in env.txt.
set -uo pipefail
cd "$(dirname "$0")/../.."
OUT=${OUT:-/tmp/jaxloco-gpu-out}
mkdir -p "$OUT"
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    || { echo "figures.sh: installing .whl/ failed (run benchmarks/gpu/wheels.sh here and carry .whl)"; exit 1; }
export PYTHONPATH="$PWD:/tmp/site${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
export JAXLOCO_CACHE_DIR=${JAXLOCO_CACHE_DIR:-/tmp/jaxloco-cache}
{
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
    python3 -c "import sys, jax, jaxlib, mujoco, mujoco.mjx; print(sys.version.split()[0], 'jax', jax.__version__, 'jaxlib', jaxlib.__version__, 'mujoco', mujoco.__version__, jax.devices())"
} 2>&1 | grep -v -i "warp" | tee "$OUT/env.txt"
HORIZON=${HORIZON:-1.0}
STEP_TIMEOUT=${STEP_TIMEOUT:-240}
run_robot() {  # robot, MJX batch sizes
    local t0=$SECONDS
    timeout "$STEP_TIMEOUT" python3 benchmarks/bench_sim.py --robots "$1" --batches 1 --mjx-batches $2 \
        --horizon "$HORIZON" 2>&1 | grep -v -i "warp" | tee "$OUT/$1.txt"
    echo "$1: exit ${PIPESTATUS[0]} after $((SECONDS - t0)) s" | tee -a "$OUT/env.txt"
}
run_robot leggrope "${LEGGROPE_BATCHES:-1024 8192 65536}"
for robot in ${ROBOTS:-snake octopus titan}; do
    run_robot "$robot" "${OTHER_BATCHES:-8192}"
done
