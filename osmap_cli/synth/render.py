"""Render: output colours from the position field, blending the copies across seams."""

import numpy as np

from osmap_kernels.render import vote_image


def render_settings(options) -> tuple[bool, int]:
    """(wrap, blend) that `synthesize` rendered with: needed to render other maps the same way.
    `options` is SynthOptions or its recorded dict (osmap info's "options")."""
    values = options if isinstance(options, dict) else vars(options)
    blend = int(values.get("blend", 0)) if values.get("method", "osmap") == "osmap" else 0
    return bool(values.get("tileable", False)), blend


def render(exemplar: np.ndarray, pos: np.ndarray, jac_field: np.ndarray | None = None,
           wrap: bool = False, blend: int = 0) -> np.ndarray:
    """float32 (H, W, C): exemplar (h, w, C) rendered through pos (H, W, 2).

    blend 0 samples the exemplar at every position (bilinear; exact copies at integer
    positions); blend r > 0 averages the votes of the neighbours within r pixels, which the
    output-to-exemplar Jacobian field jac_field (H, W, 2, 2; identity when None) carries over
    to each pixel, so the copies blend across their seams (`wrap`: the output is toroidal).
    """
    pos = np.ascontiguousarray(pos, np.float32)
    if jac_field is None:
        jac_field = np.broadcast_to(np.eye(2, dtype=np.float32), (*pos.shape[:2], 2, 2))
    return vote_image(np.ascontiguousarray(exemplar, np.float32), pos,
                      np.ascontiguousarray(jac_field, np.float32), int(blend), bool(wrap))
