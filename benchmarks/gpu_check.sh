#!/usr/bin/env bash
# The prepared GPU check of issue 38.5, for a machine with a CUDA device (under 10 minutes):
# the GPU-marked tests, then the sampler's seconds per episode on the GPU for cpu-small and
# paper-authors (naive, fast, default side by side). Run from the repository root:
#   bash benchmarks/gpu_check.sh [OUT_DIR]
set -euo pipefail
out=${1:-out/gpu_check}
mkdir -p "$out"
py=${PYTHON:-python}
"$py" -c "import torch; assert torch.cuda.is_available(), 'no CUDA device: run this on a GPU machine'; print(torch.cuda.get_device_name(0))"
"$py" -m pytest -m gpu tests/gpu -rs 2>&1 | tee "$out/gpu_tests.txt"
"$py" benchmarks/sampling_speed.py --device cuda --configs cpu-small paper-authors --repeats 5 --json 2>&1 | tee "$out/sampling_speed_cuda.txt"
