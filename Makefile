# Two commands for a fresh machine: `make demo` and `make test`. Both create .venv and install what they need.
PYTHON ?= python3
CYCLES_PYTHON ?= python3.11  # bpy 5.0.1 wheels are for CPython 3.11
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-slow bench cycles-env clean

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	$(PY) -m glint_mi.setup_llvm
	$(PY) -m glint_mi.native
	@touch $(STAMP)

demo: $(STAMP)
	$(PY) -m glint_mi.demo

test: $(STAMP)
	$(PY) -m pytest -n 2 -q

test-slow: $(STAMP)
	$(PY) -m pytest -n 2 -q -m slow

bench: $(STAMP)
	$(PY) benchmarks/bench_integrator.py
	$(PY) benchmarks/profile_step.py --ab
	@if [ -d out/demo/run/model ]; then \
		$(PY) benchmarks/bench_render_tradeoff.py out/demo/run --out benchmarks/results/render_tradeoff_demo; \
	else echo "bench: no out/demo/run (make demo first) - evaluation renders not timed"; fi

# Optional: Blender Cycles for the cross-check, in its own venv (bpy 5.0.1 pins numpy<2, ~1 GB).
cycles-env: .venv-cycles/.installed
.venv-cycles/.installed:
	$(CYCLES_PYTHON) -m venv .venv-cycles
	.venv-cycles/bin/python -m pip install -q bpy==5.0.1 OpenEXR==3.5.3
	@touch $@

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis out
