#!/usr/bin/env bash
# The prepared GPU check of issues 42 and 43 (one device call, ~9 minutes): the whole test suite under cuda_ad_rgb
# beside the demo, then one profile of the demo's trained run with issue 43's targets (1M rays a step, a 480 x 270
# view's fps, the paper's budget in minutes), alone on the machine so that its timings are clean.
# Here, once:   bash ../shared/tools/thin_wheels.sh .wheels      (ignored; pass it with carry: [".wheels"])
#               pip download --no-deps -d .wheels pytest-xdist execnet pytest-timeout   (optional: parallel suite)
# On the GPU:   bash benchmarks/gpu_check.sh [first|paper]          (results under $OUT, or ./gpu_check_out)
#   first: the suite beside the demo, then the demo run's profile and targets (above);
#   paper (~3 minutes on an H100, needs RUN, a trained run carried along, e.g. out/gpu_run): TESTS again (failures of a first
#     check), then a paper-scale step profiled (one 480 x 270 image's rays a step, 2025 patches of 8 x 8, with the
#     targets), a 1M-ray step profiled (its hit lists kept: 5 GiB), and the shell traversal on custom primitives against triangles.
#   budget (issue 65 item 3, <= 9 minutes): GLINT, 3dgs-priors and 3dgs at a GPU's budget on the declared rooms
#     9811-9812 (docs/results/gpu_budget): benchmarks/gpu_budget.py, with EXTRA (e.g. "--set traversal=shellbvh");
#     a shell-BVH check first when CuPy is there (benchmarks/bench_shellbvh.py: the same lists as the host's).
# A dry run on the CPU: NO_WHEELS=1 PY=.venv/bin/python GLINT_VARIANT=llvm_ad_rgb TESTS=tests/test_losses.py \
#               TARGET_RAYS=65536 bash benchmarks/gpu_check.sh
# Each stage has its own time limit, so a slow one still leaves the others' results. No pycolmap there: the tests
# that need it skip, and so do those that need the LLVM backend (each says why).
set -uo pipefail
cd "$(dirname "$0")/.."
out=${OUT:-gpu_check_out}; mkdir -p "$out"
PY=${PY:-python3}
if [ -z "${NO_WHEELS:-}" ]; then
    site=/tmp/glint_site; mkdir -p "$site"
    for w in .wheels/*; do "$PY" -m zipfile -e "$w" "$site"; done
    ln -sfn "$PWD/plugins" "$site/glint_mi_plugins"
    export PYTHONPATH="$site:$PWD"
fi
export GLINT_VARIANT=${GLINT_VARIANT:-cuda_ad_rgb}
{ nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv; "$PY" -c "
import glint_mi; glint_mi.set_variant(); from glint_mi.machine import summary; print(summary())"; } > "$out/summary.txt" 2>&1
t0=$SECONDS
par=(); "$PY" -c "import xdist" 2>/dev/null && par=(-n 6)
case "${1:-first}" in
budget)
    if "$PY" -c "import cupy" 2>/dev/null; then
        timeout 60 "$PY" benchmarks/bench_shellbvh.py --sizes 100000,200000 --k 16,32 --json "$out/shellbvh.json" \
            > "$out/shellbvh.md" 2>&1
        echo "shellbvh bench rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
    fi
    "$PY" benchmarks/gpu_budget.py --sfm docs/results/gpu_budget/rooms_sfm.tgz --seed 9811 --scenes 2 \
        --minutes ${MINUTES:-$(( 8 - (SECONDS - t0) / 60 ))} ${EXTRA:-} --out "$out" > "$out/budget.txt" 2>&1
    echo "gpu_budget rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
    cat "$out/summary.txt"
    exit 0;;
paper)
    run=${RUN:-out/gpu_run}
    if [ -n "${TESTS:-}" ]; then
        tmo=(); "$PY" -c "import pytest_timeout" 2>/dev/null && tmo=(--timeout 190)
        timeout 200 "$PY" -m pytest -q "${par[@]}" "${tmo[@]}" -p no:cacheprovider -rfEs --durations=12 $TESTS \
            > "$out/pytest.txt" 2>&1
        echo "pytest rc=$? ($((SECONDS - t0)) s): $(tail -1 "$out/pytest.txt")" >> "$out/summary.txt"
    fi
    # at most 8 files come back: summary, pytest, one log, the two profiles' md and json, the shell table
    log="$out/log.txt"
    timeout 70 "$PY" benchmarks/profile_step.py --run "$run" --steps 5 --warm 2 --set patches=${PAPER_PATCHES:-2025} \
        --targets --target-rays ${TARGET_RAYS:-1048576} --name gpu_paper_step --out "$out" >> "$log" 2>&1
    echo "profile $((64 * ${PAPER_PATCHES:-2025})) rays rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
    timeout 40 "$PY" benchmarks/bench_shell_mesh.py --run "$run" --name gpu ${SHELL_RES:+--res $SHELL_RES} \
        --out "$out" >> "$log" 2>&1
    echo "shell mesh rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
    timeout 90 "$PY" benchmarks/profile_step.py --run "$run" --steps 3 --warm 2 --set patches=${BIG_PATCHES:-16384} \
        --set stored_hits_mb=8192 --name gpu_1m_step --out "$out" >> "$log" 2>&1
    echo "profile $((64 * ${BIG_PATCHES:-16384})) rays rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
    cat "$out/summary.txt"
    exit 0;;
esac
tmo=(); "$PY" -c "import pytest_timeout" 2>/dev/null && tmo=(--timeout 150)
# A: the suite (default selection: not slow) and the demo side by side; the demo's speed is not a figure here.
timeout 330 "$PY" -m pytest -q "${par[@]}" "${tmo[@]}" -p no:cacheprovider -rfEs ${TESTS:-} > "$out/pytest.txt" 2>&1 &
ptest=$!
timeout 250 "$PY" -m glint_mi.demo --out /tmp/gpu_demo > "$out/demo.txt" 2>&1
echo "demo rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
cp /tmp/gpu_demo/run/metrics.json "$out/demo_metrics.json" 2>/dev/null
echo "demo shader-binding-table warnings: $(grep -c 'shader binding table' "$out/demo.txt")" >> "$out/summary.txt"
wait $ptest
echo "pytest rc=$? ($((SECONDS - t0)) s): $(tail -1 "$out/pytest.txt")" >> "$out/summary.txt"
echo "pytest shader-binding-table warnings: $(grep -c 'shader binding table' "$out/pytest.txt")" >> "$out/summary.txt"
# B: the profile and the targets, alone.
timeout 170 "$PY" benchmarks/profile_step.py --run /tmp/gpu_demo/run --steps 10 --name gpu_demo --targets \
    --target-rays "${TARGET_RAYS:-1048576}" --out "$out" > "$out/profile.txt" 2>&1
echo "profile rc=$? ($((SECONDS - t0)) s)" >> "$out/summary.txt"
cat "$out/summary.txt"
