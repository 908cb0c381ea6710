#!/usr/bin/env bash
# The prepared GPU check of issues 42 and 43 (one device call): the core tests and the device-step tests under
# cuda_ad_rgb, the demo, one profile of the demo's trained run with issue 43's targets (1M rays a step, a 480 x 270
# view's fps, the paper's budget in minutes).
# Here, once:   bash ../shared/tools/thin_wheels.sh .wheels      (ignored; pass it with carry: [".wheels"])
# On the GPU:   bash benchmarks/gpu_check.sh                       (results under $OUT, or ./gpu_check_out)
# Each stage has its own time limit, so a slow one still leaves the others' results. No pycolmap there: the tests
# that need it skip, and so do those that need the LLVM backend (each says why).
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu_check_out}; mkdir -p "$out"
site=/tmp/glint_site; mkdir -p "$site"
for w in .wheels/*; do python3 -m zipfile -e "$w" "$site"; done
ln -sfn "$PWD/plugins" "$site/glint_mi_plugins"
export PYTHONPATH="$site:$PWD" GLINT_VARIANT=cuda_ad_rgb
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv; python3 -c "
import glint_mi; glint_mi.set_variant(); from glint_mi.machine import summary; print(summary())"; } > "$out/machine.txt" 2>&1
timeout 240 python3 -m pytest -q -x -p no:cacheprovider tests/test_integrator.py tests/test_extremes.py \
    tests/test_kernels.py tests/test_objective.py tests/test_refgs.py tests/test_device_step.py \
    tests/test_losses.py > "$out/pytest_core.txt" 2>&1
echo "pytest core rc=$?" >> "$out/summary.txt"
timeout 200 python3 -m glint_mi.demo --out /tmp/gpu_demo > "$out/demo.txt" 2>&1
echo "demo rc=$?" >> "$out/summary.txt"
cp /tmp/gpu_demo/run/metrics.json "$out/demo_metrics.json" 2>/dev/null
echo "demo shader-binding-table warnings: $(grep -c 'shader binding table' "$out/demo.txt")" >> "$out/summary.txt"
timeout 150 python3 benchmarks/profile_step.py --run /tmp/gpu_demo/run --steps 10 --name gpu_demo --targets \
    --out "$out" > "$out/profile.txt" 2>&1
echo "profile rc=$?" >> "$out/summary.txt"
cat "$out/summary.txt"
