"""The tiny scene the CLI and fault tests run: 16x16 cells, a fixed elastic bar in a jet."""

from __future__ import annotations


def tiny_scene(steps: int = 4, checkpoint_every: int = 2) -> str:
    """The scene as TOML text, ``steps`` long, a checkpoint every ``checkpoint_every`` steps."""
    return TINY_SCENE.replace("steps = 4\n", f"steps = {steps}\n").replace(
        "checkpoint = { every = 2 }", f"checkpoint = {{ every = {checkpoint_every} }}")


TINY_SCENE = """
name = "tiny"
[domain]
lx = 1.0
ly = 1.0
nx = 16
[fluid]
density = 1000.0
viscosity = 1e-3
[boundaries]
top = "outflow"
[[jets]]
region = [0.4, 0.0, 0.6, 0.1]
velocity = [0.0, 0.5]
[[bodies]]
shape = { type = "rectangle", box = [0.4, 0.4, 0.6, 0.8], divisions = [2, 4] }
material = { density = 1000.0, young_modulus = 1e4, poisson_ratio = 0.3 }
fixed = { box = [0.39, 0.79, 0.61, 0.81] }
[time]
dt = 0.02
steps = 4
[coupling]
scheme = "explicit"
force_model = "momentum_exchange"
[outputs]
video = { fps = 10 }
probes = [{ kind = "node_displacement", body = 0, point = [0.5, 0.4] }, { kind = "pressure_iterations" }]
checkpoint = { every = 2 }
"""
