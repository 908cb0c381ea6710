"""One road from a run's configuration to the glint integrator: the properties a training config gives the
integrator and its shapes (:func:`integrator_props`, :func:`shape_props`), used by the trainer, by
:func:`glint_mi.evaluate.load_model` and for the saved ``model/scene.xml`` (:func:`model_xml`), so that the three
render the same model the same way."""
from __future__ import annotations

from xml.sax.saxutils import quoteattr

# the buffers training reads besides the colour (AOV groups of the integrator)
TRAINING_AOVS = "depth,normal,transparency,interface,alpha,weights"


def integrator_props(render, components: str = "all", max_hits: int | None = None, env_file: str | None = None,
                     aovs: str | None = None) -> dict:
    """The glint integrator's properties from a run's ``render`` layer (a whole TrainConfig reads through):
    ``components`` (``all``, the exact model training and evaluation use; ``auto`` or a list trade accuracy for
    speed), ``max_hits`` (default the run's), ``env_file`` (refgs: the saved directional grid; training pushes its
    own), ``aovs`` (training's buffers)."""
    cfg = render
    props = {"components": components, "max_order": cfg.max_order,
             "max_hits": cfg.max_hits if max_hits is None else max_hits, "blend": cfg.blend,
             "traversal": cfg.traversal}
    if aovs is not None:
        props["aovs"] = aovs
    if cfg.blend == "refgs":
        props["env_levels"] = cfg.env_levels
        if env_file is not None:
            props["env_file"] = env_file
    return props


def shape_props(cfg) -> dict:
    """Each glint_gaussians shape's properties for a run configured as ``cfg``."""
    return {"kernel": cfg.kernel, "opacity_shells": cfg.opacity_shells, "normal_source": cfg.normal_source}


def _prop_xml(name: str, value, indent: str) -> str:
    tag = {bool: "boolean", int: "integer", float: "float"}.get(type(value), "string")
    text = str(value).lower() if isinstance(value, bool) else str(value)
    return f'{indent}<{tag} name="{name}" value={quoteattr(text)}/>'


def model_xml(props: dict, roles: list[str], shape: dict, sensor: str = "", comment: str = "") -> str:
    """A Mitsuba scene file holding the glint integrator with ``props`` and one glint_gaussians shape per role
    (``<role>.ply`` beside the file, with ``shape``'s properties), and ``sensor`` (XML text)."""
    lines = ['<scene version="3.0.0">']
    if comment:
        lines.append(f"    <!-- {comment} -->")
    lines.append('    <integrator type="glint" id="integrator">')
    lines += [_prop_xml(k, v, " " * 8) for k, v in props.items()]
    for r in roles:
        lines.append(f'        <shape type="glint_gaussians" name="{r}">')
        lines += [_prop_xml(k, v, " " * 12) for k, v in {"filename": f"{r}.ply", **shape}.items()]
        lines.append("        </shape>")
    lines.append("    </integrator>")
    return "\n".join(lines) + "\n" + sensor + "</scene>\n"
