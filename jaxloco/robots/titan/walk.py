"""The gait planner's footsteps (`gait.plan_cycles`) executed in MuJoCo by the footstep
executor (`scenarios.make_scenario`): Sections 7 and 8.4 end to end.

Frames: the planner works in the map frame (`maps`: x up the fall line, y across, z
along the slope normal); the simulated terrain (`jaxloco.sim.terrain.frames_on_slope`
with `direction` 0) is the same plane, so the map frame is the slope frame with the same
origin and `maps.map_to_world` gives world points. The simulated frame beams are
centred on the origin at +-spacing/2, +-3 spacing/2, ... (N_BEAMS each way, reaching
about +-(N_BEAMS - 1) spacing / 2); `sim_map` builds the matching grid maps (frame
lines at spacing/2 + k spacing). The maps are periodic: keep walks inside the beams.

COG: the planner's COG is the whole-robot centre of mass; the executor places the body
so that the centre of mass with the legs (each leg is 450 kg of 7 t, up to ~7 cm off the
trunk's) is there (`control.body_for_com`).

Survey -> map -> long walk (Sec. 8.2-8.3): `field_survey` and `surveyed_map` of a frame
field such as the dummy-frame field `LONG_FIELD`, `plan_on_map` on the result; the
simulated analysis `titan.walk` (`sim_analysis.py`, spec `titan_long_walk`) executes it.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxloco.robots.titan import gait as titan_gait
from jaxloco.robots.titan import maps, scenarios
from jaxloco.robots.titan import params as titan_params

SIM_SHAPE = (120, 120)  # cells of the planning map (12 x 12 m at 0.1 m)
STEPS_PER_CYCLE = 6
# [m] kept between the pad and the frames on top of the planner's own (cell) margin: the
# executor lands feet within ~4-6 cm of the plan and the feet slip a few cm over a walk
# (benchmarks/titan_walks.py); without it a foot planned 5 cm from a frame touched it
PLACEMENT_MARGIN = 0.05

# One compilation per (map shape, n_cycles): every walk on the same grid reuses it. The
# set-up around the planner (maps, start pose, executor plan) is jitted too: run op by op
# it compiled ~500 one-operation programs in each new process (`sim_analysis.plan_row`'s
# first row, exact map: 18.4 s, now 8.6 s, most of it compiling the planner; a surveyed
# map next: 6.7 s, now 2.1 s; 6 Dec 2026, 2 cores).
_plan_cycles = jax.jit(titan_gait.plan_cycles, static_argnames="n_cycles")
_standard_start = jax.jit(titan_gait.standard_start)
_map_to_world = jax.jit(maps.map_to_world)


@jax.jit
def _free_starts(params: titan_params.TitanParams, gmap: maps.GridMap, cand, direction):
    """Whether the standard start with the COG at each candidate map xy (K, 2) along
    `direction` has all four feet on free cells (K,)."""
    feet = jax.vmap(lambda xy: titan_gait.standard_start(params, gmap, xy, direction).feet)(cand)
    return ~maps.sample_forbidden(gmap, feet[..., :2]).any(axis=1)


def sim_map(
    frame_size: float,
    spacing: float,
    slope: float = 0.0,
    shape: tuple[int, int] = SIM_SHAPE,
    cell: float = float(titan_params.CELL),
    margin: float = PLACEMENT_MARGIN,
) -> maps.GridMap:
    """Unevenness and forbidden-foothold maps of the simulated frames (`scenarios`
    terrain: beams `frame_size` wide and high every `spacing` m, centred on the origin),
    on a grid centred on the origin. frame_size 0: flat ground. The forbidden cells keep
    the pad plus `margin` off the frames (the executor's placement error)."""
    origin = -0.5 * np.asarray(shape, float) * cell
    half = 0.5 * spacing
    return maps.frame_grid_map(
        tuple(shape),
        origin,
        np.float64(cell),
        frame_size,
        spacing,
        np.array([half, half]),
        slope,
        foot_radius=float(titan_params.FOOT_RADIUS) + margin,
    )


def executor_plan(
    gait: titan_gait.GaitPlan, start: titan_gait.GaitState, gmap: maps.GridMap, direction
) -> scenarios.Plan:
    """The executor's `scenarios.Plan` (world frame) of a planned walk: feet and body
    after each step, swings, cycle ends, the path L_G of each cycle (through the COG at
    the cycle's start, along that cycle's `direction`, map-frame angle, scalar or one
    per cycle) and the planner's swing tops (frame clearance)."""
    feet = np.asarray(gait.feet_world, float)
    n_steps = feet.shape[0]
    n_cycles = n_steps // STEPS_PER_CYCLE
    body = np.asarray(gait.cog_world, float)
    body0 = np.asarray(_map_to_world(gmap, start.cog), float)
    feet0 = np.asarray(_map_to_world(gmap, start.feet), float)
    dirs = np.broadcast_to(np.asarray(direction, float), (n_cycles,))
    d_map = np.stack([np.cos(dirs), np.sin(dirs), np.zeros_like(dirs)], axis=1)
    d_world = np.asarray(_map_to_world(gmap, d_map), float)
    cycle_start = np.concatenate(
        [body0[None], body[STEPS_PER_CYCLE - 1 :: STEPS_PER_CYCLE][:-1]]
    )
    swing = np.asarray(gait.swing_leg, np.int32)
    # a cycle without swings (a change-of-direction transition shift, or a failed cycle
    # holding still) ends off the old path by design: measure it against its own end
    still = (swing.reshape(n_cycles, STEPS_PER_CYCLE) < 0).all(axis=1)
    cycle_start = np.where(
        still[:, None], body[STEPS_PER_CYCLE - 1 :: STEPS_PER_CYCLE], cycle_start
    )
    top = np.where(swing >= 0, np.asarray(gait.swing_path, float)[:, 1, 2], -np.inf)
    return scenarios.Plan(
        feet0=feet0,
        body0=body0,
        feet=feet,
        body=body,
        swing=swing,
        cycle_end=np.arange(n_steps) % STEPS_PER_CYCLE == STEPS_PER_CYCLE - 1,
        path_origin=np.repeat(cycle_start, STEPS_PER_CYCLE, axis=0),
        path_dir=np.repeat(d_world, STEPS_PER_CYCLE, axis=0),
        swing_top=top,
    )


class NoClearStart(ValueError):
    """No start pose near the requested one keeps every foot off the frames."""


def clear_start(
    params: titan_params.TitanParams,
    gmap: maps.GridMap,
    near_xy,
    direction: float = 0.0,
    search: float = 3.0,
    step: float = 0.1,
    snap: float = 0.6,
) -> titan_gait.GaitState:
    """A start pose near `near_xy` (map xy of the COG) with its four feet on free cells
    of the forbidden-foothold map: the standard start (`gait.standard_start`) nearest
    `near_xy` on a grid of `step` within +-search / 2 whose feet are all free; if there
    is none (dense frames: 0.2 m frames every 1.5 m leave no room for the standard
    stance), the standard start at `near_xy` with each foot on a frame moved to the
    nearest free cell centre within `snap` m and the COG put H_g above the new virtual
    plane. NoClearStart (a ValueError) if a foot finds no free cell."""
    near = np.asarray(near_xy, float)
    ticks = np.arange(-0.5 * search, 0.5 * search + 1e-9, step)
    cand = near + np.stack(np.meshgrid(ticks, ticks, indexing="ij"), -1).reshape(-1, 2)
    cand = cand[np.argsort(np.linalg.norm(cand - near, axis=1), kind="stable")]
    free = np.asarray(_free_starts(params, gmap, cand, direction))
    if free.any():
        return _standard_start(params, gmap, cand[int(np.argmax(free))], direction)
    start = titan_gait.standard_start(params, gmap, jnp.asarray(near), direction)
    centres = np.asarray(
        maps.cell_centres(gmap.forbidden.shape, gmap.origin, gmap.cell)
    ).reshape(-1, 2)
    ok = ~np.asarray(gmap.forbidden).reshape(-1)
    xy = np.asarray(start.feet[:, :2], float).copy()
    for leg in range(4):
        if bool(maps.sample_forbidden(gmap, jnp.asarray(xy[leg]))):
            dist = np.where(ok, np.linalg.norm(centres - xy[leg], axis=1), np.inf)
            best = int(np.argmin(dist))
            if dist[best] > snap:
                raise NoClearStart(
                    f"clear_start: foot {leg} of the start pose near {near.tolist()} "
                    f"has no free cell within {snap} m"
                )
            xy[leg] = centres[best]
    xy = jnp.asarray(xy)
    feet = jnp.concatenate([xy, maps.sample_height(gmap, xy)[:, None]], axis=1)
    nrm, off = titan_gait.virtual_plane(feet)
    cog_z = titan_gait.plane_height(nrm, off, start.cog[:2]) + params.h_g
    return titan_gait.GaitState(feet, start.cog.at[2].set(cog_z), start.yaw, start.rear)


def plan_on_map(
    params: titan_params.TitanParams,
    gmap: maps.GridMap,
    near_xy,
    n_cycles: int,
    direction=0.0,
    spacing: float = float(titan_params.GRID_SMALL),
    frame_size: float = float(titan_params.FRAME_SMALL),
    slope: float = 0.0,
) -> tuple[scenarios.Plan, titan_gait.GaitPlan, dict[str, float]]:
    """Plan `n_cycles` on the planning map `gmap` from the standard start with the COG near
    `near_xy` (map frame; `clear_start` moves it by up to 1.5 m so that no foot starts on
    a frame) along `direction` (map-frame angle [rad], scalar or one per cycle; the first
    sets the start pose). Returns the executor plan, the planner's output and the
    executor's scalar params for the simulated terrain (theta, direction, spacing,
    beam_height, tether, s_ne_c)."""
    dirs = np.broadcast_to(np.asarray(direction, float), (n_cycles,))
    start = clear_start(params, gmap, near_xy, float(dirs[0]))
    gait = _plan_cycles(params, gmap, start, n_cycles=n_cycles, direction=dirs)
    plan = executor_plan(gait, start, gmap, dirs)
    scalars = {
        "theta": float(slope),
        "direction": 0.0,
        "spacing": float(spacing),
        "beam_height": float(frame_size),
        "tether": float(params.tether),
        "s_ne_c": float(params.s_ne_c),
    }
    return plan, gait, scalars


def plan_walk(
    start_xy,
    n_cycles: int,
    direction=0.0,
    frame_size: float = float(titan_params.FRAME_SMALL),
    spacing: float = float(titan_params.GRID_SMALL),
    slope: float = 0.0,
    params: titan_params.TitanParams | None = None,
    shape: tuple[int, int] = SIM_SHAPE,
) -> tuple[scenarios.Plan, titan_gait.GaitPlan, dict[str, float]]:
    """`plan_on_map` on the exact map of the simulated frames (`sim_map`)."""
    params = titan_params.default_params() if params is None else params
    gmap = sim_map(frame_size, spacing, slope, shape)
    return plan_on_map(params, gmap, start_xy, n_cycles, direction, spacing, frame_size, slope)


# ------------------------------------------------------------ survey -> map -> long walk
# Sec. 8.3: "a plane 30 m x 5 m including frames of 0.2 m x 0.2 m". Ours: 0.2 m beams every
# 1.5 m (the Sec. 8.4 test slope's grid, which the dummy frames stand for), 21 across and
# 4 along: a field of 30.2 x 4.7 m centred on the origin, flat ground around it (80 m
# long: 60 cycles from LONG_START leave the field and return to the standard gait).
LONG_FIELD = scenarios.FrameField(n_along=4, n_across=21, max_spacing=1.5, half_length=40.0, half_width=8.0)
LONG_SPACING = 1.5  # [m]
LONG_SHAPE = (800, 120)  # planning map cells: x in [-40, 40], y in [-6, 6] m
LONG_START = (-20.0, 0.0)  # [m] start COG, 5 m before the field


def field_survey(field: scenarios.FrameField, spacing: float, frame_size: float, noise: float = 0.0,
                 key: jax.Array | None = None) -> tuple[jax.Array, jax.Array]:
    """A synthetic total-station survey (Sec. 8.2.1 step 1, `maps.survey_points`) of the
    simulated beams `field` every `spacing` m: the beam crossings measured on top and the
    area centres on the ground, each coordinate with Gaussian noise of std `noise` [m]."""
    n_nodes = (field.n_across, field.n_along)
    origin = -0.5 * spacing * (np.asarray(n_nodes, float) - 1.0)
    return maps.survey_points(n_nodes, jnp.asarray(spacing), jnp.asarray(origin), frame_size, noise=noise, key=key)


def surveyed_map(field: scenarios.FrameField, spacing: float, frame_size: float, noise: float = 0.0,
                 key: jax.Array | None = None, shape: tuple[int, int] = LONG_SHAPE,
                 margin: float = PLACEMENT_MARGIN, slope: float = 0.0) -> maps.GridMap:
    """The planning maps made from `field_survey` by our map generation
    (`maps.map_from_survey`, Sec. 8.2.1 steps 2-4), on a grid centred on the origin;
    forbidden cells keep the pad plus `margin` off the surveyed frames. The survey is in
    the plane's own frame (on a slope: x up the fall line), the map's `slope` places it."""
    return _surveyed_map(field, spacing, frame_size, noise, key, tuple(shape), float(titan_params.FOOT_RADIUS) + margin,
                         slope)


@functools.partial(jax.jit, static_argnames=("field", "shape"))
def _surveyed_map(field, spacing, frame_size, noise, key, shape, foot_radius, slope) -> maps.GridMap:
    """`surveyed_map` as one program per field and map shape (survey and map traced)."""
    nodes, centres = field_survey(field, spacing, frame_size, noise, key)
    origin = -0.5 * np.asarray(shape, float) * float(titan_params.CELL)
    cell = float(titan_params.CELL)
    return maps.map_from_survey(nodes, centres, frame_size, frame_size, shape, jnp.asarray(origin),
                                jnp.asarray(cell), foot_radius=foot_radius, slope=slope)


def converged(gait: titan_gait.GaitPlan, params: titan_params.TitanParams, last: int = 2) -> bool:
    """Back to the standard gait (Fig. 5): the last `last` cycles with |L| = |L-bar| =
    L_std (along +x, a body axis), |W| = W_std and no modification."""
    ls = np.asarray(gait.cycle_l, float)[-last:]
    ws = np.asarray(gait.cycle_w, float)[-last:]
    trials = np.asarray(gait.cycle_trials)[-last:]
    return bool(np.allclose(ls, float(params.l_std), atol=1e-6) and np.allclose(ws, float(params.w_std), atol=1e-6)
                and (trials == 0).all() and not np.asarray(gait.cycle_failed)[-last:].any())
