"""Ref-GS's own part of a run (the ``refgs`` method): its directional grid (plugins/glint_env), trained beside the
Gaussian sets. Everything the method adds to training lives here: its start, its Adam step, what it sends to the
integrator, what the checkpoint and the saved model hold. The builder attaches it to a run whose config asks for it
(:func:`glint_mi.training.builder.parts_for`); the trainer, the builder and the outputs call its hooks without knowing what it is."""
from __future__ import annotations

import io

import numpy as np

import glint_mi.conventions as cv
from glint_mi.runs import atomic_write_bytes


class DirectionalGridPart:
    """Ref-GS's directional grid: channel-major flat log-radiance (as the integrator holds it) and its Adam moments."""

    name = "refgs"

    @staticmethod
    def applies(cfg) -> bool:
        return cfg.blend == "refgs"

    def __init__(self):
        self.values = None
        self.moments = None  # (m, v, step count)

    def start(self, tr) -> None:
        """Ref-GS's starting point: roughness 0.5 (its sigmoid(0); beta carries it), the albedo composited in linear
        space (the SfM colours converted, so the first image shows them), and the directional grid at its initial
        value (glint_env)."""
        from glint_mi_plugins.glint_env import DirectionalGrid

        gs = tr.sets["interface"]
        gs.logit_specular[:] = 0.0
        colour = gs.sh[:, 0] * cv.SH_C0 + 0.5
        gs.sh[:, 0] = ((cv.srgb_to_linear(np.clip(colour, 0.0, 1.0)) - 0.5) / cv.SH_C0).astype(gs.sh.dtype)
        grid = DirectionalGrid(tr.cfg.env_levels, init=float(np.log(tr.cfg.env_init)))
        self.values = grid.data.copy()
        self.moments = (np.zeros_like(self.values), np.zeros_like(self.values), np.zeros(1))

    def load(self, tr, z: dict) -> None:
        """From a checkpoint's arrays (:meth:`state`)."""
        self.values = z["env"].astype(np.float32)
        self.moments = (z["env_adam/m"].copy(), z["env_adam/v"].copy(), z["env_adam/n"].copy())

    def state(self) -> dict:
        """The checkpoint's arrays."""
        m, v, n = self.moments
        return {"env": self.values, "env_adam/m": m, "env_adam/v": v, "env_adam/n": n}

    def push(self, tr) -> None:
        """Send the grid to the integrator, with gradients on."""
        grid = tr.integ.env
        grid.data = self.values
        grid.enable_grad()

    def step(self, tr) -> None:
        """Dense Adam on the grid (every ray reads it), then back to the integrator."""
        grid = tr.integ.env
        g = np.nan_to_num(grid.grad(), nan=0.0, posinf=0.0, neginf=0.0)
        grid.clear_grad()
        tr.adam.step_array(self.values, g, self.moments, tr.cfg.lr_env * tr.cfg.lr_multiplier)
        self.push(tr)

    def save(self, tr, model) -> None:
        """model/env.npy: the grid as [h, w, 3] log-radiance (what :meth:`push` last sent)."""
        buf = io.BytesIO()
        np.save(buf, tr.integ.env.numpy())
        atomic_write_bytes(model / "env.npy", buf.getvalue())
