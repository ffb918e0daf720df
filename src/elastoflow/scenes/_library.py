"""Built-in scenes: named factories in a registry.

The paper (METHOD section 9) gives neither physical sizes nor material constants for its two
scenes; the values chosen for them are collected in ``_PAPER_SCENE_CHOICES`` below, with the
reasoning, so that they can be tuned in one place.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from elastoflow.scenes._errors import SceneError
from elastoflow.scenes._schema import Scene
from elastoflow.scenes._schema3d import Scene3D
from elastoflow.scenes._toml import parse_scene


@dataclass(frozen=True)
class _Entry:
    factory: Callable[[], Scene | Scene3D]
    summary: str


_REGISTRY: dict[str, _Entry] = {}


def _register(name: str) -> Callable[[Callable[[], dict]], Callable[[], dict]]:
    def decorate(factory: Callable[[], dict]) -> Callable[[], dict]:
        summary = (factory.__doc__ or "").strip().splitlines()[0]

        def build() -> Scene | Scene3D:
            data = factory()
            data["name"] = name
            data.setdefault("description", summary)
            return parse_scene(data, source=f"built-in scene {name!r}")

        _REGISTRY[name] = _Entry(build, summary)
        return factory

    return decorate


def list_scenes() -> dict[str, str]:
    """Built-in scene names with a one-line summary each, in registration order."""
    return {name: entry.summary for name, entry in _REGISTRY.items()}


def get_scene(name: str) -> Scene | Scene3D:
    """A fresh copy of the built-in scene ``name``.

    Raises:
        SceneError: ``name`` is not a built-in scene (the message lists those that are).
    """
    entry = _REGISTRY.get(name)
    if entry is None:
        allowed = ", ".join(_REGISTRY)
        raise SceneError([f"scene = {name!r}: unknown scene name (built-in scenes: {allowed})"])
    return entry.factory()


# Physical choices for the paper's scenes (the paper gives only grid, dt, substeps, element
# count). Both use a 1 m x 1 m box of water-like fluid. The explicit FEM substep
# (dt / substeps) must stay below element size / sqrt((lambda + 2 mu) / rho_s); the moduli are
# soft rubber so that the published substep counts are stable on meshes of the published size.
_PAPER_SCENE_CHOICES: dict[str, dict[str, Any]] = {
    "bar_in_jet": {
        # 5 cm x 50 cm rubber-like bar hanging from y = 0.85 m; 2 x 48 divisions give 192
        # triangles (paper: 194). Substep 0.013/35 = 3.7e-4 s; ElasticBody.stable_substep() is
        # 4.8e-4 s for E = 6e4 Pa. No gravity: the paper's scene is about the jet, and a bar this
        # soft would sag under its own weight.
        "fluid_density": 1000.0,
        "fluid_viscosity": 1e-4,
        "bar_box": (0.475, 0.35, 0.525, 0.85),
        "bar_divisions": (2, 48),
        "bar_density": 1100.0,
        "bar_young_modulus": 6.0e4,
        "bar_poisson_ratio": 0.3,
        "bar_damping": 5.0,
        # A 1 m/s jet from a nozzle near the floor, 1 cm off the bar's axis so that the bar
        # bends to one side instead of only being compressed.
        "jet_region": (0.47, 0.04, 0.55, 0.10),
        "jet_velocity": (0.0, 1.0),
        # The bar weighs about a tenth of the fluid it moves sideways (added mass): the paper's
        # explicit coupling diverges there unless the force is under-relaxed (0.1, which lags
        # the force by ~10 steps); the monolithic scheme needs no relaxation. (With the explicit
        # scheme the paper's momentum exchange, eq. 8, hardly sees a steady jet: ~0.5 N/m
        # against ~24 N/m of traction, docs/validation_coupling.md.)
        "scheme": "monolithic",
        # The paper's advection (semi-Lagrangian). With MacCormack's sharper jet the bar,
        # pushed along its axis, buckles harder, and at t = 9.2 s the element at the clamp's
        # corner is crushed (det F 0.70 -> inverted within five steps) under every integrator
        # tried (energy-momentum, Newmark 0.55, midpoint; E = 9e4, damping 15): St.
        # Venant-Kirchhoff loses its stiffness in strong compression (docs/method_notes.md
        # item 8). With this advection the bar runs its 770 steps (smallest det F 0.65).
        "advection": "semi_lagrangian",
    },
    "windmill": {
        # Four 3.5 cm wide blades of 20 cm tip radius, hub pinned at its centre: 154 triangles
        # (paper: 160). Substep 0.05/100 = 5e-4 s, but the hub's outline gives elements only
        # 3 mm high: ElasticBody.stable_substep() is 5.9e-4 s with rho = 5000, E = 8e3 Pa
        # (rho = 800, E = 2e5 would need 6e-5 s). A body heavier than the fluid also keeps the
        # explicit coupling away from the added-mass instability.
        "fluid_density": 1000.0,
        "fluid_viscosity": 1e-4,
        "center": (0.62, 0.5),
        "radius": 0.2,
        "hub_radius": 0.04,
        "blade_width": 0.035,
        "element_size": 0.05,
        "density": 5000.0,
        "young_modulus": 8.0e3,
        "poisson_ratio": 0.3,
        "damping": 5.0,
        # The pipe: two static walls along x, open at both ends; a jet inside draws fluid in
        # at the back and blows it out of the mouth above the hub, so that it turns the
        # windmill. 0.3 m/s keeps the CFL number near 4 at the paper's dt = 0.05 s.
        "pipe_walls": ((0.06, 0.74, 0.32, 0.78), (0.06, 0.56, 0.32, 0.60)),
        "jet_region": (0.12, 0.60, 0.18, 0.74),
        "jet_velocity": (0.3, 0.0),
        # The monolithic scheme, unrelaxed: the windmill turns clockwise (-0.66 rad at 10 s,
        # -2.36 rad at 20 s), with the held windmill's torque (a control-volume balance of
        # angular momentum agrees with the scheme's applied torque, docs/method_notes.md
        # item 8). The explicit step needs the traction relaxed to 0.1 here (unrelaxed it
        # diverges at step 11) and gives -0.6 rad at 10 s.
        "scheme": "monolithic",
    },
}


@_register("bar_in_jet")
def _bar_in_jet() -> dict:
    """Paper Fig. 6: elastic bar, top end fixed, bottom end in a jet from below."""
    c = _PAPER_SCENE_CHOICES["bar_in_jet"]
    x0, y0, x1, y1 = c["bar_box"]
    return {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 256},
        "fluid": {"density": c["fluid_density"], "viscosity": c["fluid_viscosity"],
                  "advection": c["advection"]},
        "boundaries": {"left": "no_slip", "right": "no_slip", "bottom": "no_slip",
                       "top": "outflow"},
        "jets": [{"region": c["jet_region"], "velocity": c["jet_velocity"], "dye": 1.0}],
        "bodies": [{
            "name": "bar",
            "shape": {"type": "rectangle", "box": c["bar_box"], "divisions": c["bar_divisions"]},
            "material": {"density": c["bar_density"], "young_modulus": c["bar_young_modulus"],
                         "poisson_ratio": c["bar_poisson_ratio"],
                         "damping_lambda": c["bar_damping"], "damping_mu": c["bar_damping"]},
            "fixed": {"box": (round(x0 - 0.01, 6), round(y1 - 0.005, 6), round(x1 + 0.01, 6),
                              round(y1 + 0.005, 6))},
        }],
        "time": {"dt": 0.013, "duration": 10.0, "substeps": 35},
        "coupling": {"scheme": c["scheme"]},
        "outputs": {
            "video": {"view": "speed", "fps": 30},
            "probes": [
                {"kind": "node_displacement", "body": 0, "point": ((x0 + x1) / 2, y0)},
                {"kind": "body_force", "body": 0},
                {"kind": "pressure_iterations"},
            ],
            "checkpoint": {"every": 200},
        },
    }


@_register("windmill")
def _windmill() -> dict:
    """Paper Fig. 7: elastic windmill pivoted at its hub, turned by flow out of a pipe."""
    c = _PAPER_SCENE_CHOICES["windmill"]
    return {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 256},
        # MacCormack, as the paper-scene speed figures and the unrelaxed run were measured
        # (docs/benchmarks.md); the scene default's flux form sub-steps at this CFL of ~4.
        "fluid": {"density": c["fluid_density"], "viscosity": c["fluid_viscosity"],
                  "advection": "maccormack"},
        "boundaries": {"left": "no_slip", "right": "outflow", "bottom": "no_slip",
                       "top": "no_slip"},
        "jets": [{"region": c["jet_region"], "velocity": c["jet_velocity"], "dye": 1.0}],
        "obstacles": [{"shape": "rectangle", "box": wall} for wall in c["pipe_walls"]],
        "bodies": [{
            "name": "windmill",
            "shape": {"type": "windmill", "center": c["center"], "radius": c["radius"],
                      "hub_radius": c["hub_radius"], "blade_width": c["blade_width"],
                      "blades": 4, "element_size": c["element_size"]},
            "material": {"density": c["density"], "young_modulus": c["young_modulus"],
                         "poisson_ratio": c["poisson_ratio"],
                         "damping_lambda": c["damping"], "damping_mu": c["damping"]},
            "pivot": c["center"],
        }],
        "time": {"dt": 0.05, "duration": 20.0, "substeps": 100},
        "coupling": {"scheme": c["scheme"]},
        "outputs": {
            "video": {"view": "speed", "fps": 20},
            "meshes": {"format": "obj", "thickness": 0.05, "every": 1},
            "probes": [{"kind": "kinetic_energy", "body": 0}, {"kind": "body_force", "body": 0},
                       {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 100},
        },
    }


@_register("cavity")
def _cavity() -> dict:
    """Lid-driven cavity at Re = 100 (unit box, lid speed 1 m/s, nu = 0.01 m^2/s)."""
    return {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 64},
        # MacCormack, the scene default when this scene's pictures and runs were made.
        "fluid": {"density": 1.0, "viscosity": 0.01, "advection": "maccormack"},
        "boundaries": {"top": {"type": "moving", "velocity": 1.0}},
        "time": {"dt": 0.01, "duration": 20.0, "substeps": 1},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "every": 10},
            "probes": [{"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 500},
        },
    }


@_register("dfg_cylinder")
def _dfg_cylinder() -> dict:
    """DFG 2D-1 (Schaefer & Turek 1996): channel flow past a cylinder at Re = 20."""
    return {
        "domain": {"lx": 2.2, "ly": 0.41, "h": 0.01},
        "fluid": {"density": 1.0, "viscosity": 1e-3},
        "boundaries": {"left": {"type": "inflow", "speed": 0.3, "profile": "parabolic"},
                       "right": "outflow", "bottom": "no_slip", "top": "no_slip"},
        "obstacles": [{"shape": "circle", "center": (0.2, 0.2), "radius": 0.05}],
        "time": {"dt": 0.01, "duration": 10.0, "substeps": 1},
        "outputs": {
            "video": {"view": "vorticity", "fps": 30, "every": 5},
            "probes": [{"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 500},
        },
    }


# Turek & Hron (2006) FSI1, as collected in shared/reference/turek_hron.json: channel
# 2.5 x 0.41 m, cylinder (0.2, 0.2) r = 0.05, flag 0.35 x 0.02 m clamped on the cylinder at
# x = 0.2 + sqrt(0.05^2 - 0.01^2); rho_f = rho_s = 1000, nu_f = 1e-3, E = 1.4 MPa, nu_s = 0.4,
# mean inflow 0.2 m/s (peak 0.3), cosine ramp over 2 s.
_FLAG_LEFT_X = 0.2 + (0.05**2 - 0.01**2) ** 0.5


@_register("flag")
def _flag() -> dict:
    """Turek-Hron FSI1: channel, cylinder, inflow and the flag of FSI1 (rho_s = rho_f).

    The explicit coupling diverges here within 0.6-1.6 s of flow time whatever the relaxation
    (0.1 to 0.03, h = 0.01 or 0.005): the flag moves broadside ~4x its own mass of fluid. The
    monolithic scheme runs it unrelaxed. 42 cells across the 0.41 m channel (h = 0.41/42,
    the channel 257 cells = 2.509 m long) keep the flag's long edges off the grid lines, where
    they would shake it from step to step (docs/method_notes.md item 9). The benchmark itself,
    with its quantities: ``elastoflow validate turek-hron FSI1``.
    """
    return {
        "domain": {"lx": 257 * 0.41 / 42, "ly": 0.41, "h": 0.41 / 42},
        # MacCormack, as the Turek-Hron runs of docs/validation/turek-hron.md.
        "fluid": {"density": 1000.0, "viscosity": 1e-3, "advection": "maccormack"},
        "boundaries": {"left": {"type": "inflow", "speed": 0.3, "profile": "parabolic",
                                "ramp_time": 2.0},
                       "right": "outflow", "bottom": "no_slip", "top": "no_slip"},
        "obstacles": [{"shape": "circle", "center": (0.2, 0.2), "radius": 0.05}],
        "bodies": [{
            "name": "flag",
            "shape": {"type": "rectangle", "box": (_FLAG_LEFT_X, 0.19, 0.6, 0.21),
                      "divisions": (35, 2)},
            "material": {"density": 1000.0, "young_modulus": 1.4e6, "poisson_ratio": 0.4},
            "fixed": {"box": (_FLAG_LEFT_X - 0.005, 0.185, _FLAG_LEFT_X + 0.001, 0.215)},
        }],
        "time": {"dt": 0.005, "duration": 5.0, "substeps": "auto"},
        "coupling": {"scheme": "monolithic"},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "every": 10},
            "probes": [{"kind": "node_displacement", "body": 0, "point": (0.6, 0.2)},
                       {"kind": "body_force", "body": 0}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 1000},
        },
    }


@_register("jet_in_box")
def _jet_in_box() -> dict:
    """Fluid only: a dyed jet rising in a closed box."""
    return {
        "domain": {"lx": 1.0, "ly": 1.0, "nx": 128},
        # MacCormack, the scene default when this scene's pictures and runs were made.
        "fluid": {"density": 1.0, "viscosity": 1e-4, "advection": "maccormack"},
        "jets": [{"region": (0.46, 0.02, 0.54, 0.06), "velocity": (0.0, 0.8), "dye": 1.0}],
        "time": {"dt": 0.01, "duration": 10.0, "substeps": 1},
        "outputs": {
            "video": {"view": "dye", "fps": 30, "every": 2},
            "probes": [{"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 500},
        },
    }


# Reeds: h = 2/256 = 7.8 mm. Each reed is a 0.25 m rod (32 cells, 24 segments) of a 1 cm
# plate, E = 4.8e7 Pa: EI = E t^3 / 12 = 4 N m, mass 10 kg/m^2 (the water's over 1 cm). The
# reeds block half the channel, so the stream over them runs at about twice the inflow: at
# EI = 1 N m they were bent by 0.09 m at t = 0.6 s with the inflow still ramping; at 4 N m they
# bend clearly and stay off the floor. Their feet sit a third of a cell off the cell centres
# and faces (a rod exactly on the centres' line leaks 1.6e-3 of its flux:
# docs/method_notes.md item 4).
_REED_FEET_X = (0.7 + 0.3 / 128, 0.95 + 0.3 / 128, 1.2 + 0.3 / 128, 1.45 + 0.3 / 128)


@_register("reeds")
def _reeds() -> dict:
    """Four elastic reeds (rods) clamped to a channel floor, swaying in a cylinder's wake.

    Rods are lines of zero thickness for the fluid, blocked by the thin-body cuts, and are
    advanced by the monolithic scheme (docs/architecture.md, "Rods"); the same scene with
    triangle reeds: examples/reeds_in_a_channel.toml.
    """
    return {
        "domain": {"lx": 2.0, "ly": 0.5, "nx": 256},
        # MacCormack, the scene default when this scene's pictures and runs were made.
        "fluid": {"density": 1000.0, "viscosity": 5e-4, "advection": "maccormack"},
        "boundaries": {"left": {"type": "inflow", "speed": 0.4, "ramp_time": 1.0},
                       "right": "outflow", "bottom": "no_slip", "top": "free_slip"},
        "obstacles": [{"shape": "circle", "center": (0.3, 0.3), "radius": 0.06}],
        "bodies": [{
            "name": f"reed {k + 1}",
            "shape": {"type": "rod", "points": [(x, 0.0), (x, 0.25)], "segments": 24},
            "material": {"density": 1000.0, "young_modulus": 4.8e7, "thickness": 0.01,
                         "damping_time": 0.01},
            "clamped": ["start"],
        } for k, x in enumerate(_REED_FEET_X)],
        "time": {"dt": 0.01, "steps": 300},
        "coupling": {"scheme": "monolithic"},
        "outputs": {
            "video": {"view": "vorticity", "fps": 30, "every": 2},
            "probes": [{"kind": "node_displacement", "body": 1, "point": (_REED_FEET_X[1], 0.25)},
                       {"kind": "body_force", "body": 1}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 100},
        },
    }


# Martin & Moyce's (1952) n^2 = 2 column (../shared/reference/free_surface.json,
# "martin_moyce_1952_dam_break"): a = 2.25 in, the column a wide and 2 a tall.
_DAM_A = 2.25 * 0.0254


@_register("dam_break")
def _dam_break() -> dict:
    """Free surface: Martin & Moyce's water column (a = 2.25 in, 2 a tall) collapsing in a tank.

    The tank is 8 a long and 4 a tall, 256 x 128 cells (a / 32), no-slip walls, water in air
    (a void at pressure 0). The surge runs along the floor, hits the far wall at about
    0.35 s and runs up it. The level set is redistanced every step (the redistancing no longer
    thickens the film that runs up the far wall, which gained energy before: E/E0 at most
    1.018, docs/method_notes.md item 12). The surge front against the experiment and the
    energy: docs/validation/free_surface.md.
    """
    a = _DAM_A
    return {
        "domain": {"lx": 8 * a, "ly": 4 * a, "nx": 256},
        "fluid": {"density": 1000.0, "viscosity": 1e-6, "gravity": (0.0, -9.81),
                  "advection": "maccormack"},
        "liquid": {"boxes": [(0.0, 0.0, a, 2 * a)]},
        "boundaries": {"left": "no_slip", "right": "no_slip", "bottom": "no_slip",
                       "top": "no_slip"},
        "time": {"cfl": 0.5, "duration": 1.0},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "every": 4},
            "probes": [{"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 500},
        },
    }


@_register("sloshing")
def _sloshing() -> dict:
    """Free surface: the first sloshing mode in a tank (air-water-vv: 0.1 m tank, 5 mm wave).

    Tank 0.1 m x 0.1 m, water 0.05 m deep with a cosine surface of amplitude 5 mm
    (../shared/reference/free_surface.json, "standing_wave_linear_dispersion"), free-slip
    walls, 64 x 64 cells; the period of the linear dispersion relation is 0.374 s
    (docs/validation/free_surface.md: the frequency within 0.7 % at this resolution).
    """
    return {
        "domain": {"lx": 0.1, "ly": 0.1, "nx": 64},
        "fluid": {"density": 1000.0, "viscosity": 0.0, "gravity": (0.0, -9.81),
                  "advection": "maccormack"},
        "liquid": {"height": "0.05 + 0.005 * cos(pi * x / 0.1)"},
        "boundaries": {"left": "free_slip", "right": "free_slip", "bottom": "free_slip",
                       "top": "free_slip"},
        "time": {"dt": 0.002, "duration": 1.2},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "every": 2},
            "probes": [{"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 200},
        },
    }


# The floating scene's bodies: (name, density [kg/m^3], Young's modulus [Pa], outline).
# Densities 0.3, 0.5 and 0.8 of the water's float; the box of density 2 sinks and comes to
# rest on the floor (wall contact, coupling.wall_contact); the 0.8 disc is soft enough to
# be seen to squash as it hits the water.
_FLOATING_BODIES: tuple[tuple[str, float, float, dict[str, Any]], ...] = (
    ("light box (0.3)", 300.0, 2e6,
     {"type": "rectangle", "box": (0.16, 0.46, 0.36, 0.54), "divisions": (16, 6)}),
    ("half box (0.5)", 500.0, 2e6,
     {"type": "rectangle", "box": (0.52, 0.50, 0.68, 0.60), "divisions": (12, 8)}),
    ("soft disc (0.8)", 800.0, 2e5,
     {"type": "polygon", "element_size": 0.0125,
      "points": [(0.95 + 0.06 * math.cos(2 * math.pi * k / 32),
                  0.52 + 0.06 * math.sin(2 * math.pi * k / 32)) for k in range(32)]}),
    ("dense box (2)", 2000.0, 2e6,
     {"type": "rectangle", "box": (0.40, 0.44, 0.48, 0.52), "divisions": (8, 8)}),
)


@_register("floating")
def _floating() -> dict:
    """Free surface with bodies: four elastic bodies of different densities dropped into water.

    Tank 1.2 m x 0.6 m, water 0.35 m deep, free-slip walls, 96 x 48 cells; a light box, a box
    of half the water's density, a soft disc and a box twice as dense as water fall from a few
    centimetres above the surface and splash; the first three bob and settle towards their
    Archimedes drafts, the dense one sinks and rests on the floor (the strong coupling with the
    free surface, `FreeSurfaceMonolithicCoupling`, and wall contact; the draft's validation:
    docs/validation/free_surface.md). The liquid is a hundred times as viscous as water
    (1e-4 m^2/s) to damp the bobbing; still, at 4 s the bodies bob by about a centimetre
    (as with 1e-5: the waves they send out come back from the tank's walls).
    """
    return {
        "domain": {"lx": 1.2, "ly": 0.6, "nx": 96},
        "fluid": {"density": 1000.0, "viscosity": 1e-4, "gravity": (0.0, -9.81),
                  "advection": "semi_lagrangian"},
        "liquid": {"height": 0.35, "viscosity": "whole_grid"},
        "boundaries": {"left": "free_slip", "right": "free_slip", "bottom": "free_slip",
                       "top": "free_slip"},
        "bodies": [{"name": name, "shape": shape,
                    "material": {"density": density, "young_modulus": young,
                                 "poisson_ratio": 0.3}}
                   for name, density, young, shape in _FLOATING_BODIES],
        "coupling": {"scheme": "monolithic"},
        "time": {"dt": 0.0025, "duration": 5.0},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "every": 13},
            "probes": [{"kind": "node_displacement", "body": 0, "point": (0.26, 0.5)},
                       {"kind": "node_displacement", "body": 1, "point": (0.6, 0.55)},
                       {"kind": "node_displacement", "body": 2, "point": (0.95, 0.52)},
                       {"kind": "body_force", "body": 1},
                       {"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 400},
        },
    }


# Antoci, Gallati & Sibilla's (2007) rubber gate (../shared/reference/free_surface.json,
# "antoci2007_elastic_gate"): a water column A wide and H tall held by a rubber gate S thick,
# clamped at its top to a rigid wall and free over its lower L, G above the floor. E and the
# Poisson ratio as CoCoNuT's Kratos case uses them (the codes disagree on Poisson: 0.4, 0.47,
# 0.49); the tank is SPHinXsys' numerical one, 0.5 m long. Plane strain: the gate is a plate
# as wide as the tank.
ELASTIC_GATE: dict[str, Any] = {
    "column": (0.1, 0.14), "gate_thickness": 0.005, "gate_length": 0.079,
    "clearance": 0.0025, "tank": (0.5, 0.2),
    "solid_density": 1100.0, "young_modulus": 1e7, "poisson_ratio": 0.4,
    "fluid_density": 1000.0, "viscosity": 1e-6, "duration": 0.4,
    # Linear triangles are stiff in bending unless several span the thickness: the gate's
    # peak opening at 40.4 cells across the column grew by 13 % from 2 to 4 elements across
    # and by 2.7 % from 4 to 8 (docs/validation/free_surface.md), so the mesh is 8 x 128,
    # whatever the fluid's grid.
    "gate_divisions": (8, 128),
}


def _walled_tank(c: dict[str, Any], lx: float, ly: float, h: float) -> dict[str, Any]:
    """The part of a free-surface FSI scene ``c`` (`ELASTIC_GATE`, `DAM_BREAK_OBSTACLE`)
    that both share: a no-slip tank ``lx`` x ``ly`` of cells ``h``, water in the column at
    the left, MacCormack advection, the strong coupling, CFL 0.5, and the outputs (video,
    the body's force, energy, iterations; the probe of a node goes first, added by the
    scene)."""
    width, height = c["column"]
    return {
        "domain": {"lx": lx, "ly": ly, "h": h},
        "fluid": {"density": c["fluid_density"], "viscosity": c["viscosity"],
                  "gravity": (0.0, -9.81), "advection": "maccormack"},
        "liquid": {"boxes": [(0.0, 0.0, width, height)]},
        "boundaries": {"left": "no_slip", "right": "no_slip", "bottom": "no_slip",
                       "top": "no_slip"},
        "coupling": {"scheme": "monolithic"},
        "time": {"cfl": 0.5, "duration": c["duration"]},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "every": 6},
            "probes": [{"kind": "body_force", "body": 0},
                       {"kind": "kinetic_energy"}, {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 400},
        },
    }


def elastic_gate_data(cells_across_column: float = 60.4) -> dict:
    """The `elastic_gate` scene as data with ``h = A / cells_across_column``.

    A whole number of cells across the column would put the gate's faces on grid lines, where
    the faces along the clamped gate flip between fluid and solid with the smallest motion
    (docs/method_notes.md item 9): the default 60.4 keeps them a tenth of a cell off. The tank
    is a whole number of cells, a little longer and taller than 0.5 x 0.2 m (the far wall and
    the lid are far from the flow).
    """
    c = ELASTIC_GATE
    width = c["column"][0]
    thickness, length, clearance = c["gate_thickness"], c["gate_length"], c["clearance"]
    h = width / cells_across_column
    tank_x, tank_y = c["tank"]
    nx, ny = math.ceil(tank_x / h - 1e-9), math.ceil(tank_y / h - 1e-9)
    top = clearance + length
    data = _walled_tank(c, nx * h, ny * h, h)
    # The rigid wall that holds the water above the gate, from the gate's clamp up.
    data["obstacles"] = [{"shape": "rectangle", "box": (width, top, width + thickness, ny * h)}]
    data["bodies"] = [{
        "name": "gate",
        "shape": {"type": "rectangle", "box": (width, clearance, width + thickness, top),
                  "divisions": c["gate_divisions"]},
        "material": {"density": c["solid_density"], "young_modulus": c["young_modulus"],
                     "poisson_ratio": c["poisson_ratio"]},
        "fixed": {"box": (width - 0.25 * h, top - 0.25 * h, width + thickness + 0.25 * h,
                          top + 0.25 * h)},
    }]
    data["outputs"]["probes"].insert(0, {"kind": "node_displacement", "body": 0,
                                         "point": (width + 0.5 * thickness, clearance)})
    return data


@_register("elastic_gate")
def _elastic_gate() -> dict:
    """Free surface with a body: a water column pushes open a rubber gate (Antoci et al. 2007).

    Water 0.1 m wide and 0.14 m tall behind a 5 mm rubber gate (1100 kg/m^3, E = 10 MPa,
    Poisson 0.4) clamped at its top, its lower 79 mm free, 2.5 mm above the floor; a rigid
    wall holds the water above the gate. Released at rest, the gate bends open and the water
    runs out under it. 1.66 mm cells (3 across the gate), 8 x 128 elements, monolithic
    coupling with the free surface. The gate tip's displacement at three resolutions:
    docs/validation/free_surface.md.
    """
    return elastic_gate_data()


# Walhorn et al.'s (2005) dam break onto an elastic obstacle (../shared/reference/
# free_surface.json, "walhorn2005_dam_break_flexible_obstacle"): a column L wide and 2 L tall
# (L = 0.146 m) in a 4 L tank, an elastic wall 12 mm thick and 80 mm tall clamped to the floor
# at x = 2 L. The solid's density as Walhorn and Kratos give it (solids4foam uses 2700).
DAM_BREAK_OBSTACLE: dict[str, Any] = {
    "column": (0.146, 0.292), "tank": 0.584, "obstacle": (0.292, 0.012, 0.08),
    "solid_density": 2500.0, "young_modulus": 1e6, "poisson_ratio": 0.0,
    "fluid_density": 1000.0, "viscosity": 1e-6, "duration": 1.0,
    # 2 mm elements: the wall's peak bending at 30.4 cells across the column moved by 8 %
    # from 3 x 23 elements to 6 x 40 and by 1 % from there to 12 x 80.
    "obstacle_divisions": (6, 40),
}


def dam_break_obstacle_data(cells_across_column: float = 41.4) -> dict:
    """The `dam_break_obstacle` scene as data with ``h = L / cells_across_column``.

    With a whole number of cells across the column the obstacle's upstream face (at 2 L) lies
    on a grid line; the default 41.4 keeps both its faces a fifth of a cell off the lines and
    puts 3.4 cells across it. The tank is a whole number of cells, 1.6 mm longer and taller
    than 4 L at the default (the far wall is 0.28 m past the obstacle).
    """
    c = DAM_BREAK_OBSTACLE
    width = c["column"][0]
    left, thickness, tall = c["obstacle"]
    h = width / cells_across_column
    cells = math.ceil(c["tank"] / h - 1e-9)
    data = _walled_tank(c, cells * h, cells * h, h)
    data["bodies"] = [{
        "name": "obstacle",
        "shape": {"type": "rectangle", "box": (left, 0.0, left + thickness, tall),
                  "divisions": c["obstacle_divisions"]},
        "material": {"density": c["solid_density"], "young_modulus": c["young_modulus"],
                     "poisson_ratio": c["poisson_ratio"]},
        "fixed": {"box": (left - 0.25 * h, -0.25 * h, left + thickness + 0.25 * h, 0.25 * h)},
    }]
    data["outputs"]["probes"].insert(0, {"kind": "node_displacement", "body": 0,
                                         "point": (left, tall)})
    return data


@_register("dam_break_obstacle")
def _dam_break_obstacle() -> dict:
    """Free surface with a body: a dam break hits an elastic wall on the floor (Walhorn 2005).

    A water column 0.146 m wide and 0.292 m tall collapses in a 0.584 m tank onto an elastic
    wall 12 mm thick and 80 mm tall (2500 kg/m^3, E = 1 MPa, Poisson 0) clamped to the floor
    0.146 m past the column (6 x 40 elements); the surge bends it, jumps over it and hits
    the far wall. 3.5 mm cells (3.4 across the wall), monolithic coupling with the free
    surface. The wall's top corner over time at three resolutions:
    docs/validation/free_surface.md.
    """
    return dam_break_obstacle_data()


# --------------------------------------------------------------------------------------------
# 3D scenes (a [domain] with lz)


@_register("sphere_drag")
def _sphere_drag() -> dict:
    """3D: uniform flow past a fixed sphere at Re 100 (D = 1 m, U = 1 m/s, nu = 0.01 m^2/s).

    The set-up of ../shared/reference/three_d.json (``flow_past_fixed_sphere``) in a 12 x 6 x
    6 D box at 8 cells per diameter: inflow 3 D upstream, outflow 9 D downstream, free-slip
    sides. The force probe's x component over ``0.5 rho U^2 pi D^2 / 4`` is the drag
    coefficient (published 1.08-1.10; docs/validation/three_d.md has the resolution and box
    studies behind it).
    """
    return {
        "domain": {"lx": 12.0, "ly": 6.0, "lz": 6.0, "h": 0.125, "origin": (-3.0, -3.0, -3.0)},
        "fluid": {"density": 1.0, "viscosity": 0.01, "initial_velocity": (1.0, 0.0, 0.0)},
        "boundaries": {"left": {"type": "inflow", "speed": 1.0}, "right": "outflow",
                       "bottom": "free_slip", "top": "free_slip", "back": "free_slip",
                       "front": "free_slip"},
        "obstacles": [{"shape": "sphere", "name": "sphere", "center": (0.0, 0.0, 0.0),
                       "radius": 0.5}],
        "time": {"cfl": 1.0, "duration": 12.0},
        "outputs": {
            "video": {"view": "vorticity", "fps": 15, "axis": "z", "at": 0.0},
            "probes": [{"kind": "force", "obstacles": [0]},
                       {"kind": "pressure_iterations"}],
            "checkpoint": {"every": 50},
        },
    }


# ../shared/reference/three_d.json, "richter_3d_elastic_block_in_channel", the form that
# solids4foam ships ("modified_form_solids4foam"), mirrored to the whole channel (z from 0).
ELASTIC_BLOCK_3D: dict[str, Any] = {
    "channel": (1.5, 0.4, 0.8), "block": (0.45, 0.0, 0.2, 0.55, 0.2, 0.6),
    "fluid_density": 1000.0, "viscosity": 1e-3, "peak_velocity": 0.3, "ramp_time": 1.0,
    "solid_density": 1000.0, "young_modulus": 1e4, "poisson_ratio": 0.4,
    "point_a": (0.45, 0.15, 0.25),
}


@_register("elastic_block_3d")
def _elastic_block_3d() -> dict:
    """3D: a soft block clamped to a channel's floor, bent by the flow (Richter's benchmark in
    the form solids4foam ships; ../shared/reference/three_d.json).

    A 0.1 x 0.2 x 0.4 m block (E = 10 kPa, Poisson 0.4, as dense as the water) in a 1.5 x 0.4
    x 0.8 m channel, paraboloid inflow of 0.3 m/s at its centre reached in 1 s (Re 60 on the
    block's height), monolithic coupling (the explicit step diverges at this density ratio).
    Published: point A on the block's upstream face moves by (14.63, 5.0, -0.45) mm at steady
    state (docs/validation/three_d.md). 0.025 m cells and elements (4 across the block): the
    linear tetrahedra are then 15 % too stiff in bending, and A moves 11.6 mm; with 0.0125 m
    elements 12.9 mm, at 3 s a step instead of 0.2 (docs/method_notes.md item 16).
    """
    c = ELASTIC_BLOCK_3D
    lx, ly, lz = c["channel"]
    x0, y0, z0, x1, y1, z1 = c["block"]
    return {
        "domain": {"lx": lx, "ly": ly, "lz": lz, "h": 0.025},
        "fluid": {"density": c["fluid_density"], "viscosity": c["viscosity"],
                  "advection": "maccormack"},
        "boundaries": {"left": {"type": "inflow", "speed": c["peak_velocity"],
                                "profile": "parabolic", "ramp_time": c["ramp_time"]},
                       "right": "outflow", "bottom": "no_slip", "top": "no_slip",
                       "back": "no_slip", "front": "no_slip"},
        "bodies": [{
            "name": "block",
            "shape": {"type": "box", "box": (x0, y0, z0, x1, y1, z1), "element_size": 0.025},
            "material": {"density": c["solid_density"], "young_modulus": c["young_modulus"],
                         "poisson_ratio": c["poisson_ratio"]},
            "fixed": {"box": (x0 - 0.01, y0 - 0.01, z0 - 0.01, x1 + 0.01, y0 + 0.001,
                              z1 + 0.01)},
        }],
        "coupling": {"scheme": "monolithic"},
        "time": {"dt": 0.02, "duration": 5.0},
        "outputs": {
            "video": {"view": "speed", "fps": 25, "axis": "z", "at": 0.4},
            "probes": [
                {"kind": "node_displacement", "body": 0, "point": c["point_a"]},
                {"kind": "body_force", "body": 0},
                {"kind": "pressure_iterations"},
            ],
            "checkpoint": {"every": 50},
        },
    }


@_register("bar_in_jet_3d")
def _bar_in_jet_3d() -> dict:
    """3D: the paper's Fig. 6 in real 3D, a rubber bar hanging in a jet from below, 64^3.

    The 2D scene's bar (5 cm square, 50 cm long, fixed at its top, E = 60 kPa) and 1 m/s
    jet, 1 cm off the bar's axis in x and z. The explicit scheme (the 3D scenes' default)
    needs a body heavier than the fluid it moves sideways: the bar is 3000 kg/m^3 (added mass
    about 0.4 of its own), where the 2D scene's 1100 would diverge without relaxation.
    """
    c = _PAPER_SCENE_CHOICES["bar_in_jet"]
    x0, y0, x1, y1 = c["bar_box"]
    z0, z1 = 0.475, 0.525
    return {
        "domain": {"lx": 1.0, "ly": 1.0, "lz": 1.0, "nx": 64},
        "fluid": {"density": c["fluid_density"], "viscosity": c["fluid_viscosity"],
                  "advection": "semi_lagrangian"},
        "boundaries": {"left": "no_slip", "right": "no_slip", "bottom": "no_slip",
                       "top": "outflow", "back": "no_slip", "front": "no_slip"},
        "jets": [{"region": (0.47, 0.04, 0.47, 0.55, 0.10, 0.55), "velocity": (0.0, 1.0, 0.0),
                  "dye": 1.0}],
        "bodies": [{
            "name": "bar",
            "shape": {"type": "box", "box": (x0, y0, z0, x1, y1, z1),
                      "divisions": (2, 20, 2)},
            "material": {"density": 3000.0, "young_modulus": c["bar_young_modulus"],
                         "poisson_ratio": c["bar_poisson_ratio"],
                         "damping_lambda": c["bar_damping"], "damping_mu": c["bar_damping"]},
            "fixed": {"box": (x0 - 0.01, y1 - 0.005, z0 - 0.01, x1 + 0.01, y1 + 0.005,
                              z1 + 0.01)},
        }],
        "time": {"dt": 0.013, "duration": 10.0},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "axis": "z", "at": 0.5},
            "probes": [
                {"kind": "node_displacement", "body": 0, "point": ((x0 + x1) / 2, y0, z0)},
                {"kind": "body_force", "body": 0},
                {"kind": "pressure_iterations"},
            ],
            "checkpoint": {"every": 200},
        },
    }


@_register("flag_3d")
def _flag_3d() -> dict:
    """3D: a light flag behind a pole flutters in a stream (64x32x32, monolithic coupling).

    A pole (a cylinder obstacle along y, 0.1 m across, Re 100 at the 1 m/s inflow) holds a
    flag L = 0.5 m long, H = 0.4 m high (aspect ratio H/L = 0.8), h = 0.08 m (2.6 cells)
    thick. Flag flutter (Eloy et al. 2008, JFM 611; Shelley & Zhang 2011) is set by the
    mass ratio M* = rho_f L / (rho_s h) and the reduced velocity U* = U L sqrt(rho_s h / B),
    B = E h^3 / (12 (1 - nu^2)) per unit span. Here rho_s = 6.25 kg/m^3 against the fluid's
    1: M* = 1; E = 5.84 Pa, Poisson 0.45: B = 3.1e-4 N m, U* = 20. Eloy et al.'s threshold at M* = 1 for
    H/L ~ 1 is U* ~ 10 (their linear theory; their plates flutter a little above it): this
    flag sits twice above it, still ~1.6x when the linear tetrahedra's bending locking (2
    across the thickness: ~1.5x too stiff, tests/validation/test_cantilever3d.py) is
    counted. Poisson 0.45 since at 0.3 the bulk modulus (5.6 Pa) let the pressure of the starting
    flow squash the whole flag (det F 0.35 at 0.5 s); the inflow ramps up over 2 s from rest
    for the same reason. So light a flag needs the monolithic coupling. The pole sits 1 cm (a
    third of a cell) off the mid plane z = 0.5 to break the mirror symmetry. Measured (20 s,
    3-5 min on two shared cores): the trailing edge flutters across the stream at 0.40 Hz
    (f L / U = 0.20), amplitude 2.6 cm, settled from t ~ 3 s on; smallest det F 0.87. At
    U* = 6 it only quivers (2.8 mm); docs/validation/three_d.md ("A flag flutters").
    """
    return {
        "domain": {"lx": 2.0, "ly": 1.0, "lz": 1.0, "nx": 64},
        "fluid": {"density": 1.0, "viscosity": 1e-3, "advection": "maccormack"},
        "boundaries": {"left": {"type": "inflow", "speed": 1.0, "ramp_time": 2.0},
                       "right": "outflow", "bottom": "free_slip", "top": "free_slip",
                       "back": "free_slip", "front": "free_slip"},
        "obstacles": [{"shape": "cylinder", "name": "pole", "center": (0.4, 0.5, 0.51),
                       "radius": 0.05, "length": 1.0, "axis": "y"}],
        "bodies": [{
            "name": "flag",
            "shape": {"type": "box", "box": (0.45, 0.3, 0.46, 0.95, 0.7, 0.54),
                      "divisions": (16, 12, 2)},
            "material": {"density": 6.25, "young_modulus": 5.84, "poisson_ratio": 0.45},
            "fixed": {"box": (0.44, 0.29, 0.45, 0.46, 0.71, 0.55)},
        }],
        "coupling": {"scheme": "monolithic"},
        "time": {"cfl": 0.8, "duration": 20.0},
        "outputs": {
            "video": {"view": "vorticity", "fps": 30, "axis": "y", "at": 0.5},
            "probes": [
                {"kind": "node_displacement", "body": 0, "point": (0.95, 0.5, 0.5)},
                {"kind": "force", "bodies": [0], "obstacles": [0]},
                {"kind": "pressure_iterations"},
            ],
            "checkpoint": {"every": 200},
        },
    }


# ten Cate et al. (2002), case E1 (../shared/reference/three_d.json,
# tencate2002_settling_sphere): a 15 mm sphere of 1120 kg/m^3 released 120 mm above the floor
# of a closed 100 x 160 x 100 mm box of oil (970 kg/m^3, 0.373 Pa s: Re 1.5).
TEN_CATE_E1: dict[str, Any] = {
    "box": (0.1, 0.16, 0.1),
    "diameter": 0.015,
    "sphere_density": 1120.0,
    "gap": 0.12,
    "fluid_density": 970.0,
    "dynamic_viscosity": 0.373,
    "gravity": 9.81,
}


@_register("sphere_settling")
def _sphere_settling() -> dict:
    """3D: ten Cate et al. (2002) case E1, a sphere settling in a box of oil (Re 1.5).

    The elastic sphere (E = 100 kPa: its weight strains it by ~2e-4, a rigid sphere to the
    flow) starts at rest 8 diameters above the floor. Published: it reaches 0.036 m/s in the
    box (docs/validation/three_d.md). Six cells per diameter; y is up. The monolithic
    coupling (the explicit one lets the sphere vibrate itself apart in this viscous oil at
    t = 2 s: docs/method_notes.md item 14), with the energy-momentum rule's numerical damping
    at its largest, 1: no elastic mode of this sphere is resolved by the step (omega dt ~ 40),
    and at the default 0.1 the sphere chattered on its lowest node after landing (the contact
    mode, docs/method_notes.md item 15). The damping is objective: it does not act on the
    rigid motion, so the settling speed is the same.
    """
    c = TEN_CATE_E1
    lx, ly, lz = c["box"]
    h = c["diameter"] / 6.0
    radius = 0.5 * c["diameter"]
    return {
        "domain": {"lx": lx, "ly": ly, "lz": lz, "h": h},
        "fluid": {"density": c["fluid_density"],
                  "viscosity": c["dynamic_viscosity"] / c["fluid_density"],
                  "gravity": (0.0, -c["gravity"], 0.0)},
        "boundaries": {"left": "no_slip", "right": "no_slip", "bottom": "no_slip",
                       "top": "no_slip", "back": "no_slip", "front": "no_slip"},
        "bodies": [{
            "name": "sphere",
            "shape": {"type": "sphere", "center": (0.5 * lx, c["gap"] + radius, 0.5 * lz),
                      "radius": radius, "element_size": h},
            "material": {"density": c["sphere_density"], "young_modulus": 1e5,
                         "poisson_ratio": 0.3, "damping_lambda": 1.0, "damping_mu": 1.0},
        }],
        "coupling": {"scheme": "monolithic", "numerical_damping": 1.0},
        "time": {"dt": 0.01, "duration": 4.0},
        "outputs": {
            "video": {"view": "speed", "fps": 30, "axis": "z"},
            "probes": [
                {"kind": "node_displacement", "body": 0,
                 "point": (0.5 * lx, c["gap"] + radius, 0.5 * lz)},
                {"kind": "body_force", "body": 0},
                {"kind": "pressure_iterations"},
            ],
            "checkpoint": {"every": 100},
        },
    }
