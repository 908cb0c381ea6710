"""Evaluation: image, geometry and transparency metrics (:mod:`.metrics`), analyses of trained runs
(:mod:`.analysis`), the speed/accuracy trade (:mod:`.tradeoff`) and plots (:mod:`.plots`). The command is
``python -m glint_mi.evaluate``."""
