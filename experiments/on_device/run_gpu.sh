#!/usr/bin/env bash
# The torch backend's figures on one accelerator: the GPU machine's one command (under 8 minutes, code
# generation included: every row, the numba one first, checks the time left, and one that would pass
# --budget-s is listed as skipped; an extra --seconds above half the budget is refused before any work).
#
# On a bare machine (torch, numpy, numba, scipy, gymnasium and msgspec installed; no internet needed after that):
#     pip install --no-deps -e .        # the package, nothing else
#     bash experiments/on_device/run_gpu.sh
# Writes experiments/on_device/results/device_throughput_<device>.json and .md (the table names the GPU,
# torch and CUDA). Extra arguments go to benchmarks/device_throughput.py (e.g. --n-envs 1024 65536).
set -euo pipefail
cd "$(dirname "$0")/../.."
device="${DEVICE:-cuda}"
out="experiments/on_device/results/device_throughput_${device//:/_}.json"
exec python benchmarks/device_throughput.py --device "$device" --compile --profile --budget-s 400 --out "$out" "$@"
