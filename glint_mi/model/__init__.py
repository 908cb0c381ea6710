"""The model: Gaussian sets (:mod:`.gaussians`), the one road from a config to the integrator's properties and the
model folder's writer and reader (:mod:`.files`), and rendering helpers (:mod:`.render`). The Mitsuba plugins that
trace the sets are in ``plugins/`` (imported as ``glint_mi_plugins``)."""
