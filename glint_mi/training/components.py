"""``components: auto`` — what a scene needs, as a policy object of its own (:class:`ComponentsPolicy`): which of the
secondary sets (transmission, reflection) a run keeps, decided before training from the glass cue and at the end of
densification from the evidence, each decision with its reason (``report.json``'s ``components``), and the 3DGS
profile a lone interface trains with. The policy decides; the trainer acts (drops a set, reconfigures, logs)."""
from __future__ import annotations

import numpy as np

NO_GLASS_WHY = "no glass (the transmission set is dropped): a diffuse surface's Fresnel floor is its colour's"


class ComponentsPolicy:
    """The decisions of ``components: auto`` for one run (``cfg``: its TrainConfig).

    ``dropped`` (role -> why) and ``decisions`` (role -> {kept, iteration, why}) are its state; a checkpoint keeps
    both (:meth:`state_dict`)."""

    def __init__(self, cfg):
        self.cfg = cfg
        self.dropped: dict[str, str] = {}
        self.decisions: dict[str, dict] = {}

    # ------------------------------------------------------------- state
    def kept(self, roles) -> list[str]:
        """``roles`` less the dropped ones, in their order."""
        return [r for r in roles if r not in self.dropped]

    def record(self, role: str, kept: bool, iteration: int, why: str) -> None:
        self.decisions[role] = {"kept": bool(kept), "iteration": int(iteration), "why": why}
        if not kept:
            self.dropped[role] = why

    def state_dict(self) -> dict:
        return {"dropped": dict(self.dropped), "decisions": dict(self.decisions)}

    def load_state_dict(self, state: dict) -> None:
        self.dropped = dict(state.get("dropped", {}))
        self.decisions = dict(state.get("decisions", {}))

    # ------------------------------------------------------------- before training
    def glass_cue_drops(self, roles, has_albedo: bool, has_cue: bool) -> dict[str, str]:
        """Before training: the sets to drop (role -> why). The transmission set needs a glass cue to learn from:
        an albedo prior (the paper's masks: dark albedo, bright interface, the transmission set behind), or, with
        ``trans_cue: auto``, the SfM see-through cue against an aligned depth prior. Without one (no priors: a phone
        capture) L_trans has only the depth gap between two sets that fit the same surfaces, which turns an opaque
        room into glass (the fox: 92 % of the wallpaper 'behind' when L_trans starts): the set is dropped, with the
        reflection set (what glass would mirror)."""
        c = self.cfg
        if c.components != "auto" or "transmission" not in roles or c.trans_masks in ("gt", "prior"):
            return {}
        if has_albedo or (c.trans_cue == "auto" and has_cue):
            return {}
        why = ("no glass cue: no albedo prior" + (" read (trans_albedo: off)" if c.trans_albedo == "off" else "")
               + (" and no depth prior aligned to SfM tracks" if c.trans_cue == "auto"
                  else " (trans_cue: auto adds the SfM see-through cue of a depth prior)")
               + ", so L_trans could only compare two sets that fit the same surfaces (components: all keeps them)")
        drops = {"transmission": why}
        if "reflection" in roles:  # what the glass would mirror: no glass, no reflection set
            drops["reflection"] = NO_GLASS_WHY
        return drops

    def no_glass_profile(self) -> dict | None:
        """With both secondary sets dropped before training, the interface alone is a radiance field: the fields
        that make it the ``3dgs`` method (``no_glass: 3dgs``; ``3dgs+sfm`` keeps glint_mi's SfM depth term), or None
        (``no_glass: glint``: GLINT's surfels and weights)."""
        c = self.cfg
        if c.no_glass not in ("3dgs", "3dgs+sfm"):
            return None
        from glint_mi.config import flatten
        from glint_mi.methods import METHODS

        m = flatten(METHODS["3dgs"].overrides)
        # blend: with both extra sets gone GLINT's Fresnel weights give everything to the diffuse term, the same
        # image as plain alpha compositing up to float rounding; the 3dgs blend makes it bit for bit the 3dgs method
        fields = ("kernel", "blend", "w_l1", "w_dssim", "w_consistency", "normal_weight", "clone_opacity",
                  "split_mode", "cap_schedule") + (
            ("w_sfm_depth",) if c.no_glass == "3dgs" else ())
        return {**{k: m[k] for k in fields}, "normal_source": "axis"}  # 3DGS's ellipsoids: their own axis

    # ------------------------------------------------------------- during training
    def decide_at(self) -> dict[str, int]:
        """The iteration (1-based) at which each secondary set is decided: the end of densification (the paper's 21k
        of 60k), once the set has had time to learn."""
        c = self.cfg
        return {"transmission": c.at(max(c.densify_until, c.trans_from + 0.1)),
                "reflection": c.at(max(c.densify_until, c.reflection_from + 0.1))}

    def due(self, iteration: int, roles) -> list[str]:
        """The sets decided at ``iteration`` (1-based): present, not yet decided."""
        if self.cfg.components != "auto":
            return []
        return [r for r, at in self.decide_at().items() if r in roles and r not in self.decisions and at == iteration]

    def decide(self, role: str, history: list[dict], roles) -> tuple[bool, str]:
        """Keep ``role``? (kept, why) from the training history (log rows)."""
        c = self.cfg
        recent = history[-max(5, c.log_every * 5):]
        share = np.mean([h.get(f"share_{role}", 0.0) for h in recent]) if recent else 0.0
        if role == "transmission":
            # L_trans's transparent mask alone decides, averaged over every batch since L_trans started (its coverage
            # swings between batches and with opacity resets); docs/decisions.md has the measurements
            since = [h["mask_t"] for h in history if "mask_t" in h]
            cover = float(np.mean(since)) if since else 0.0
            return cover >= c.auto_trans_min, (
                f"L_trans transparent mask covers {100 * cover:.2f} % of sampled pixels (threshold "
                f"{100 * c.auto_trans_min:.2f} %); the set's share of the image energy {100 * share:.2f} %")
        # GLINT's reflection set is what the glass interface mirrors. Without glass (no transmission set kept) the
        # 4 % Fresnel floor of a diffuse surface is not separable from its colour: dropped (docs/decisions.md)
        glass = "transmission" in roles and "transmission" not in self.dropped
        keep = share >= c.auto_contrib_min and glass
        return keep, (f"share of image energy k_s c_R = {100 * share:.2f} % (threshold {100 * c.auto_contrib_min:.2f} "
                      f"%); " + ("a transmission set is kept (glass)" if glass else
                                 "no glass (no transmission set): a diffuse surface's Fresnel floor is its colour's"))
