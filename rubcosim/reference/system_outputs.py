"""The recorded outputs of an assembled system: their names, and the kernel writing them.

Compiled per model like :mod:`.system`, whose forces it reads (:mod:`.specialize`
copies both).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rubcosim.components.hybrid_dispatch import hybrid_output_names, hybrid_outputs
from rubcosim.components.jit import njit
from rubcosim.components.stator import MODE_FREE, MODE_STICK, contact_geometry

# ruff: noqa: F405
from .layout import *  # noqa: F403
from .system import (
    bearing_force,
    contact_force,
    control_force,
    force_for_contact_laws,
    stator_centre,
)


def output_names(ip: np.ndarray) -> list[str]:
    """Names of the outputs written by :func:`outputs`, in the same order."""
    if ip[IP_FAMILY] >= FAMILY_HYBRID:
        return hybrid_output_names(int(ip[IP_FAMILY]) - FAMILY_HYBRID)
    names = ["rotor.x", "rotor.y", "rotor.vx", "rotor.vy"]
    if ip[IP_ROTOR_JOURNAL_X] >= 0:
        names += ["rotor.journal_x", "rotor.journal_y", "rotor.journal_vx", "rotor.journal_vy"]
    if ip[IP_STATOR] != STATOR_NONE:
        names += ["stator.gap", "stator.normal_force", "stator.contact"]
    if ip[IP_STATOR_CASING_X] >= 0:
        names += [f"stator.casing_{v}" for v in ("x", "y", "vx", "vy")]
    if ip[IP_BEARING] != BEARING_NONE:
        names += ["bearing.fx", "bearing.fy"]
    if ip[IP_CONTROLLER] != CONTROLLER_NONE:
        names += ["controller.ux", "controller.uy"]
    return names


@nb.njit(cache=True, inline="always")
def copy_body(y, j, out, i):
    """A planar body's (x, y, vx, vy) from state slot j to output slot i; the next slot."""
    for q in range(4):
        out[i + q] = y[j + q]
    return i + 4


@njit(borrows=True)
def outputs(t, y, yd, mode, p, ip, out):
    """Recorded outputs (see :func:`output_names`); ``stator.contact`` and
    a hybrid unit's ``contact`` are 0 free, 1 in contact or sliding, 2 sticking."""
    if ip[IP_FAMILY] >= FAMILY_HYBRID:
        hybrid_outputs(ip[IP_FAMILY] - FAMILY_HYBRID, t, y, mode, p, out)
        return
    i = copy_body(y, 0, out, 0)
    j = ip[IP_ROTOR_JOURNAL_X]
    if j >= 0:
        i = copy_body(y, j, out, i)
    if ip[IP_STATOR] != STATOR_NONE:
        cx, cy, _, _ = stator_centre(y, p, ip)
        out[i] = p[P_STATOR_CLEARANCE] - contact_geometry(y[0] - cx, y[1] - cy)[0]
        fx, fy = force_for_contact_laws(t, y, yd, mode, p, ip)
        _, _, n = contact_force(fx, fy, y, mode, p, ip)
        out[i + 1] = n
        out[i + 2] = 0.0 if mode == MODE_FREE else (2.0 if mode == MODE_STICK else 1.0)
        i += 3
    c = ip[IP_STATOR_CASING_X]
    if c >= 0:
        i = copy_body(y, c, out, i)
    if ip[IP_BEARING] != BEARING_NONE:
        bx, by = bearing_force(y, p, ip)
        out[i] = bx
        out[i + 1] = by
        i += 2
    if ip[IP_CONTROLLER] != CONTROLLER_NONE:
        ux, uy = control_force(t, y, yd, p, ip)
        out[i] = ux
        out[i + 1] = uy
