"""Evaluation: image, geometry and transparency metrics (:mod:`.metrics`), rendering a run's views and writing its
evaluation (:mod:`.renders`), the depth each method reports (:mod:`.depth_rules`), analyses of trained runs
(:mod:`.analysis`) and plots (:mod:`.plots`). It imports nothing from training (training imports it); the command is
``python -m glint_mi.evaluate``, the speed/accuracy study :mod:`glint_mi.tradeoff`."""
