"""Procedural 3D-FRONT-T-style rooms with a glass display case, path-traced ground truth and dataset export.

``python -m glint_mi.dataset make OUT --scenes 5 --seed 0 --preset bench`` writes one folder per scene (see
:mod:`glint_mi.dataset.generate`).
"""
