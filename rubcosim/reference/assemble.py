"""Assemble validated units into one monolithic system (the ``p``/``ip`` arrays)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from rubcosim.components.bearing import oilfilm_sigma
from rubcosim.components.controller import base_delay
from rubcosim.components.graph import ModelGraph, UnitNode, model_scales
from rubcosim.components.hybrid_dispatch import hybrid_types
from rubcosim.components.parameters import ParameterError
from rubcosim.components.registry import REGISTRY
from rubcosim.components.stator import damping_from_restitution, reduced_mass

from . import system as S

# Relative size of the rebound normal speed (to the system's velocity scale)
# below which chattering is declared over and the contact becomes sustained.
DEFAULT_CHATTER_TOL = 1e-10


@dataclass
class System:
    """A monolithic system ready for either engine."""

    family: int
    p: np.ndarray
    ip: np.ndarray
    y0: np.ndarray
    mode0: int
    state_names: list[str]
    state_scale: np.ndarray
    output_names: list[str]
    forcing_period: float
    velocity_scale: float
    units: dict[str, UnitNode] = field(default_factory=dict)

    @property
    def n_state(self) -> int:
        return int(self.y0.shape[0])

    @property
    def has_delay(self) -> bool:
        return self.family == S.FAMILY_ROTOR and self.ip[S.IP_CONTROL] != S.CONTROL_NONE

    def min_delay(self) -> float:
        return float(self.p[S.P_TAU0] - self.p[S.P_EPS]) if self.has_delay else math.inf


def _state_scale(
    units: Mapping[str, UnitNode], names: list[str], length: float, vscale: float
) -> np.ndarray:
    """Each state's scale (m or m/s) from the scale kind its unit type declares."""
    kinds = REGISTRY.state_scales({role: u.type for role, u in units.items()})
    by_kind = {"length": length, "velocity": vscale}
    return np.array([by_kind[kinds[name]] for name in names])


def build_system(
    model: ModelGraph | Mapping[str, UnitNode], chatter_tol: float = DEFAULT_CHATTER_TOL
) -> System:
    """Compile a model (its graph, or just its units) into one monolithic system.

    The rotor's disc carries the unbalance, the stator contact and the
    controller force; the bearing acts on the journal of a two-mass rotor.
    """
    units = model.units if isinstance(model, ModelGraph) else dict(model)
    whole = [u for u in units.values() if u.declaration.hybrid is not None]
    if whole:
        extra = sorted(set(units) - {whole[0].role})
        if extra:
            raise ParameterError(
                f"unit {extra[0]!r} cannot be combined with {whole[0].role}.type = "
                f"{whole[0].type!r}, a whole model"
            )
        return _hybrid_system(whole[0], chatter_tol)
    if "rotor" not in units:
        raise ParameterError("the scenario needs a 'rotor' or an 'oscillator' unit")
    return _rotor_system(units, chatter_tol)


def _hybrid_system(u: UnitNode, chatter_tol: float) -> System:
    """A hybrid unit type's kernels as the system (:mod:`rubcosim.components.hybrid_dispatch`)."""
    declared = u.declaration
    kernels = declared.hybrid
    params = {**u.params, "chatter_tol": chatter_tol}
    y0, mode0 = kernels.initial(params)
    packed = kernels.parameters(params)  # no inputs: the unit is the whole model
    p = np.zeros(max(S.N_P, packed.size))
    p[: packed.size] = packed
    ip = np.zeros(S.N_IP, dtype=np.int64)
    ip[S.IP_FAMILY] = S.FAMILY_HYBRID + hybrid_types().index(declared)
    ip[S.IP_NSTATE] = len(y0)
    ip[S.IP_JOURNAL] = -1
    ip[S.IP_CASING] = -1
    scales = model_scales({u.role: u})
    names = [f"{u.role}.{s.name}" for s in declared.states]
    return System(
        family=int(ip[S.IP_FAMILY]),
        p=p,
        ip=ip,
        y0=np.array(y0, dtype=float),
        mode0=int(mode0),
        state_names=names,
        state_scale=_state_scale({u.role: u}, names, scales.length, scales.velocity),
        output_names=S.output_names(ip),
        forcing_period=scales.forcing_period,
        velocity_scale=scales.velocity,
        units={u.role: u},
    )


def _rotor_system(units: Mapping[str, UnitNode], chatter_tol: float) -> System:
    rotor = units["rotor"]
    r = rotor.params
    stator = units.get("stator")
    bearing = units.get("bearing")
    controller = units.get("controller")
    two_mass = rotor.type == "two_mass"
    if bearing is not None and not two_mass:
        raise ParameterError(
            "bearing: a bearing needs rotor.type = 'two_mass' (it holds the journal)"
        )
    if two_mass and bearing is None:
        raise ParameterError("rotor.type = 'two_mass' needs a 'bearing' unit for its journal")
    w = r["speed"]
    if bearing is not None and bearing.type == "oilfilm" and w <= 0.0:
        raise ParameterError("rotor.speed must be > 0 with an oil-film bearing")

    p = np.zeros(S.N_P)
    ip = np.zeros(S.N_IP, dtype=np.int64)
    ip[S.IP_FAMILY] = S.FAMILY_ROTOR
    p[S.P_M] = r["mass"]
    p[S.P_C] = r["damping"]
    p[S.P_K] = r["stiffness"]
    p[S.P_E] = r["eccentricity"]
    p[S.P_W] = w
    p[S.P_G] = r["gravity"]
    p[S.P_RD] = r["disc_radius"]
    names = ["rotor.x", "rotor.y", "rotor.vx", "rotor.vy"]
    y0 = [r["x0"], r["y0"], r["vx0"], r["vy0"]]
    ip[S.IP_JOURNAL] = -1
    ip[S.IP_CASING] = -1

    if two_mass:
        ip[S.IP_ROTOR] = S.ROTOR_TWO_MASS
        ip[S.IP_JOURNAL] = len(y0)
        p[S.P_MJ] = r["journal_mass"]
        p[S.P_CJ] = r["journal_damping"]
        p[S.P_CSH] = r["shaft_damping"]
        names += ["rotor.journal_x", "rotor.journal_y", "rotor.journal_vx", "rotor.journal_vy"]
        y0 += [r["journal_x0"], r["journal_y0"], r["journal_vx0"], r["journal_vy0"]]
        b = bearing.params
        if bearing.type == "linear":
            ip[S.IP_BEARING] = S.BEARING_LINEAR
            p[S.P_KB] = b["stiffness"]
            p[S.P_CB] = b["damping"]
        else:
            ip[S.IP_BEARING] = S.BEARING_OILFILM
            p[S.P_CR] = b["clearance"]
            p[S.P_SIGMA] = oilfilm_sigma(
                b["viscosity"], w, b["radius"], b["length"], b["clearance"]
            )
            if math.hypot(r["journal_x0"], r["journal_y0"]) >= b["clearance"]:
                raise ParameterError(
                    "rotor.journal_x0/journal_y0 put the journal outside the bearing clearance"
                )

    if stator is not None:
        s = stator.params
        p[S.P_D] = s["clearance"]
        p[S.P_X0] = s["x_offset"]
        p[S.P_Y0] = s["y_offset"]
        p[S.P_MU] = s["friction"]
        p[S.P_R] = s["restitution"]
        if stator.type == "rigid":
            ip[S.IP_STATOR] = S.STATOR_RIGID
            if math.hypot(r["x0"] - s["x_offset"], r["y0"] - s["y_offset"]) > s["clearance"]:
                raise ParameterError(
                    "rotor.x0/rotor.y0 start the disc beyond the rigid stator's clearance"
                )
        else:
            ip[S.IP_STATOR] = S.STATOR_ELASTIC if stator.type == "elastic" else S.STATOR_CASING
            p[S.P_KC] = s["contact_stiffness"]
            m_eff = r["mass"]
            if stator.type == "casing":
                m_eff = reduced_mass(r["mass"], s["mass"])
                ip[S.IP_CASING] = len(y0)
                p[S.P_MS] = s["mass"]
                p[S.P_KS] = s["stiffness"]
                p[S.P_CSC] = s["damping"]
                names += [f"stator.casing_{v}" for v in ("x", "y", "vx", "vy")]
                y0 += [s["x0"], s["y0"], s["vx0"], s["vy0"]]
            cc = s["contact_damping"]
            p[S.P_CC] = (
                cc
                if cc >= 0.0
                else damping_from_restitution(s["restitution"], s["contact_stiffness"], m_eff)
            )

    if controller is not None:
        c = controller.params
        tau0 = base_delay(c, w)
        ip[S.IP_CONTROL] = S.CONTROL_POSITION if c["feedback"] == "position" else S.CONTROL_VELOCITY
        p[S.P_KCTL] = c["gain"]
        p[S.P_TAU0] = tau0
        p[S.P_EPS] = c["modulation_amplitude"]
        p[S.P_NU] = c["modulation_frequency"]
        p[S.P_TON] = c["t_on"]

    scales = model_scales(units)
    length, vscale, omega = scales.length, scales.velocity, scales.frequency
    p[S.P_VCHAT] = chatter_tol * vscale
    p[S.P_OMEGA_B] = omega
    n = len(y0)
    ip[S.IP_NSTATE] = n
    scale = _state_scale(units, names, length, vscale)
    return System(
        family=S.FAMILY_ROTOR,
        p=p,
        ip=ip,
        y0=np.array(y0, dtype=float),
        mode0=S.MODE_FREE,
        state_names=names,
        state_scale=scale,
        output_names=S.output_names(ip),
        forcing_period=scales.forcing_period,
        velocity_scale=vscale,
        units=dict(units),
    )
