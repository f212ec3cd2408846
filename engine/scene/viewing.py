"""
The observer's view of a booth: where the camera of the exported scenes stands, where it looks
and how wide it sees.

The camera stands at ``observer.position_mm`` and looks at ``observer.look_at_mm`` with +z up:
forward ``f = (t − e)/|t − e|``, right ``r = f × z / |f × z|``, up ``u = r × f``.  Its field of
view frames the booth's floor (``interior`` width × depth at z = 0) with a relative margin ``m``:
over the four floor corners ``p``, with ``d = p − e``,

    tan(α_x/2) = (1 + m) · max |d·r| / (d·f),    tan(α_y/2) = (1 + m) · max |d·u| / (d·f)

and the image is :data:`IMAGE_WIDTH_PX` wide, ``IMAGE_WIDTH_PX · tan(α_y/2)/tan(α_x/2)`` high.
The USD stage's camera (``usd_stage``) and the Blender file's (``bakers/blender_export``) use it.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["observer_view", "FRAME_MARGIN", "IMAGE_WIDTH_PX"]

#: the camera frames the floor with this relative margin
FRAME_MARGIN = 0.05
#: width of the camera's image (its height follows the field of view)
IMAGE_WIDTH_PX = 960


def observer_view(ir) -> dict:
    """The observer's camera of a compiled booth (see the module docstring).

    Returns
    -------
    dict
        ``position_mm``, ``look_at_mm``, unit vectors ``forward``, ``right``, ``up``, the fields of
        view ``angle_x_rad`` and ``angle_y_rad``, and ``resolution`` ``[width, height]`` in px.
    """
    eye = np.asarray(ir.observer.position_mm, float)
    target = np.asarray(ir.observer.look_at_mm, float)
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    up0 = np.array([0.0, 0.0, 1.0]) if abs(fwd[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    right = np.cross(fwd, up0)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    w, d = ir.interior.width_mm / 2, ir.interior.depth_mm / 2
    corners = np.array([[x, y, 0.0] for x in (-w, w) for y in (-d, d)]) - eye
    depth = corners @ fwd
    tx = np.max(np.abs(corners @ right) / depth) * (1 + FRAME_MARGIN)
    ty = np.max(np.abs(corners @ up) / depth) * (1 + FRAME_MARGIN)
    height = max(2, int(round(IMAGE_WIDTH_PX * ty / tx)))
    return {"position_mm": eye.tolist(), "look_at_mm": target.tolist(), "right": right.tolist(),
            "up": up.tolist(), "forward": fwd.tolist(), "angle_x_rad": float(2 * math.atan(tx)),
            "angle_y_rad": float(2 * math.atan(ty)), "resolution": [IMAGE_WIDTH_PX, height]}
