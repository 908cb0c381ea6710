"""Each run's in-run test curves (its convergence.csv) against training minutes, defaults against the switch:
    python docs/results/coarse_to_fine/figure.py OUT.png LABEL=BENCHMARK_FOLDER ... (glint's runs in each folder)"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from glint_mi.benchmark import convergence_curves  # noqa: E402
from glint_mi.evaluation.plots import convergence_figure  # noqa: E402

curves = {}
for spec in sys.argv[2:]:
    label, folder = spec.split("=", 1)
    curves.update(convergence_curves(Path(folder), "glint", label))
convergence_figure(curves, Path(sys.argv[1]))
print(len(curves), "runs ->", sys.argv[1])
