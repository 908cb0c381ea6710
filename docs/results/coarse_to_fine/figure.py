"""Each run's in-run test curves (its convergence.csv) against training minutes, defaults against the switch:
    python docs/results/coarse_to_fine/figure.py OUT.png LABEL=BENCHMARK_FOLDER ... (glint's runs in each folder)"""
import csv, sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parents[3]))
from glint_mi.evaluation.plots import convergence_figure
out = Path(sys.argv[1]); curves = {}
for spec in sys.argv[2:]:
    label, folder = spec.split("=")
    for f in sorted(Path(folder).glob("runs/*/glint/convergence.csv")):
        with open(f) as fh:
            curves[f"{label} / {f.parent.parent.name}"] = list(csv.DictReader(fh))
convergence_figure(curves, out)
print(len(curves), "runs ->", out)
