#!/usr/bin/env bash
# Run HERE (a CPU machine with pip and the internet), in the repository root, before a
# GPU session's device call: downloads into .whl/ (git-ignored) the Python 3.12 x86-64
# wheels that jaxloco needs and the device image lacks. The image (the device tool's
# KINDS.md, "Python packages already there") has Python 3.12, jax / jaxlib 0.11.2 with
# the CUDA 13 plugin, numpy, scipy, optax, pyarrow, rich, typer's click and shellingham,
# cloudpickle, flatbuffers, absl-py and etils, but no MuJoCo, MJX, pydantic or typer.
# The versions are the ones CI installs (pyproject.toml's ranges). About 27 MB; the
# working tree and the wheels travel together (64 MiB at most).
#
#   bash benchmarks/gpu/wheels.sh          # then: the device call of benchmarks/gpu/figures.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
PY=${PYTHON:-python3}
WHEELS=(
    mujoco==4.0.1 mujoco-core==4.0.1 mujoco-mjx==3.17.0  # mujoco-studio (the viewer) is not needed
    glfw==2.11.0 pyopengl==3.1.10 trimesh==5.2.0
    pydantic==2.14.4 pydantic-core==2.50.5 annotated-types==0.8.0 typing-inspection==0.4.5
    typer==0.28.0 annotated-doc==0.0.7
)
rm -rf .whl && mkdir -p .whl
for w in "${WHEELS[@]}"; do
    "$PY" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
        --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d .whl "$w" 2>&1 | grep -v '^WARNING: Location' || true
done
ls .whl
du -sh .whl
