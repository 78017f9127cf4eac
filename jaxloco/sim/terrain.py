"""Terrains whose parameters change per simulation without recompiling the MuJoCo model.

Every terrain piece is a *mocap body* (a direct child of the world body) holding one box geom at
the body origin. The box half sizes are fixed when the model is built; terrain parameters
(inclination, heights, positions ...) only move and rotate the pieces, through `mocap_pos` and
`mocap_quat`, which are per-simulation state in both the native `mujoco.batch` backend and MJX.
Heights are made by sinking tall boxes so that their top face is where it should be.

A `Terrain` is therefore a static structure (pieces: names, half sizes, fragility) plus a pure
JAX function from parameter values (and a PRNG key, for random terrains) to the poses of the
pieces: `place(values, key) -> (pos (P, 3), quat (P, 4))`, jit-, vmap- and grad-able.

Conventions: SI units (m, N), radians, world frame with z up, quaternions (w, x, y, z) as in
MuJoCo. A slope with inclination `theta` and uphill gradient azimuth `direction` (measured from
world +x about +z) is the plane z = tan(theta) * (x cos(direction) + y sin(direction)); its unit
normal is (-sin(theta) cos(direction), -sin(theta) sin(direction), cos(theta)). The *slope
frame* of such a plane has x along the uphill gradient, y horizontal (across the slope) and z
along the normal; `slope_axes` gives its x and y axes in world coordinates.

Collision filtering: robot geoms use (contype, conaffinity) = (ROBOT_CONTYPE, ROBOT_CONAFFINITY)
and terrain geoms (TERRAIN_CONTYPE, TERRAIN_CONAFFINITY), so robots collide with the terrain,
terrain pieces never collide with each other (nor robot geoms with robot geoms).

Fragile footholds (`footholds`) carry a touch sensor over their top face; `collapse_update` and
`drop_away` are the pure-JAX collapse model a controller loop applies to their mocap poses.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxloco.analysis import Param
from jaxloco.errors import SpecError

Array = jax.Array
PlaceFn = Callable[[dict[str, Array], Array], tuple[Array, Array]]

ROBOT_CONTYPE, ROBOT_CONAFFINITY = 1, 2
TERRAIN_CONTYPE, TERRAIN_CONAFFINITY = 2, 1

# Half thickness [m] of a fragile piece's touch site beyond the geom margin: the site is a thin
# box centred on the top face, so contact points (midway into the penetration) lie inside it.
# (MuJoCo also counts a contact whose point, cast along the contact normal towards the other
# body, hits the site; a site just above the face works too, one below the contact does not.)
TOUCH_HALF_THICKNESS = 0.005

DEFAULT_RGBA = (0.62, 0.60, 0.55, 1.0)
FRAGILE_RGBA = (0.85, 0.40, 0.20, 1.0)

TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi


# ----------------------------------------------------------------------------- quaternions
def quat_mul(a: Array, b: Array) -> Array:
    """Hamilton product a * b of quaternions (..., 4), (w, x, y, z): rotate by b, then by a."""
    aw, ax, ay, az = (a[..., i] for i in range(4))
    bw, bx, by, bz = (b[..., i] for i in range(4))
    return jnp.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def quat_z(yaw: Array) -> Array:
    """Unit quaternion (..., 4) of the rotation by `yaw` (rad) about the z axis."""
    half = 0.5 * jnp.asarray(yaw)
    zero = jnp.zeros_like(half)
    return jnp.stack([jnp.cos(half), zero, zero, jnp.sin(half)], -1)


def quat_tilt(normal: Array) -> Array:
    """Unit quaternion (..., 4) of the smallest rotation taking +z to the unit vector `normal`
    (..., 3). Undefined for normal = -z (the only singular direction)."""
    nx, ny, nz = normal[..., 0], normal[..., 1], normal[..., 2]
    w = 1.0 + nz
    q = jnp.stack([w, -ny, nx, jnp.zeros_like(w)], -1)
    return q / jnp.sqrt(2.0 * w)[..., None]


def quat_to_matrix(q: Array) -> Array:
    """Rotation matrix (..., 3, 3) of the unit quaternion q (..., 4), (w, x, y, z)."""
    w, x, y, z = (q[..., i] for i in range(4))
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return jnp.stack([jnp.stack(r, -1) for r in rows], -2)


def quat_z_axis(q: Array) -> Array:
    """Third column of the rotation of q (..., 4): the body z axis (a box's top-face normal) in
    world coordinates, (..., 3)."""
    w, x, y, z = (q[..., i] for i in range(4))
    return jnp.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)


# ---------------------------------------------------------------------- planes and boxes
def slope_normal(theta: Array, direction: Array) -> Array:
    """Unit normal (..., 3), world frame, of the plane with inclination `theta` (rad) whose
    uphill gradient points at azimuth `direction` (rad from world +x)."""
    theta, direction = jnp.broadcast_arrays(jnp.asarray(theta), jnp.asarray(direction))
    s = jnp.sin(theta)
    return jnp.stack([-s * jnp.cos(direction), -s * jnp.sin(direction), jnp.cos(theta)], -1)


def slope_axes(theta: Array, direction: Array) -> tuple[Array, Array]:
    """World-frame x axis (unit uphill tangent) and y axis (horizontal, across the slope) of the
    slope frame of the plane (theta, direction); each (..., 3)."""
    theta, direction = jnp.broadcast_arrays(jnp.asarray(theta), jnp.asarray(direction))
    c, s = jnp.cos(direction), jnp.sin(direction)
    uphill = jnp.stack([jnp.cos(theta) * c, jnp.cos(theta) * s, jnp.sin(theta)], -1)
    across = jnp.stack([-s, c, jnp.zeros_like(s)], -1)
    return uphill, across


def box_pose_from_top(top_centre: Array, normal: Array, yaw: Array, half_size: Any) -> tuple[Array, Array]:
    """Pose of a box given the centre of its top face.

    top_centre (..., 3) [m, world] and `normal` (..., 3, normalised here) are the top face's
    centre and outward normal; `half_size` (3,) or (..., 3) [m]. The box orientation is the
    smallest tilt taking +z to `normal` applied after a rotation by `yaw` (rad) about the box's
    own z axis, so for normal = slope_normal(theta, d) and yaw = d the box x axis points uphill.
    Returns pos (..., 3) (the box centre, half_size_z below the top along -normal) and
    quat (..., 4), (w, x, y, z).
    """
    normal = jnp.asarray(normal)
    n = normal / jnp.linalg.norm(normal, axis=-1, keepdims=True)
    quat = quat_mul(quat_tilt(n), quat_z(yaw))
    half_z = jnp.asarray(half_size)[..., 2]
    pos = jnp.asarray(top_centre) - half_z[..., None] * n
    return pos, quat


def pad_poses(centres: Array, normals: Array, thickness: float) -> tuple[Array, Array]:
    """Poses (pos (n, 3), quat (n, 4)) of foothold pads of the given `thickness` [m] whose
    top-face centres are `centres` (n, 3) [m, world] with outward normals `normals` (n, 3)
    (normalised here). The yaw is the smallest tilt's (yaw 0 in `box_pose_from_top`)."""
    centres = jnp.asarray(centres)
    yaw = jnp.zeros(centres.shape[:-1], centres.dtype)
    half = jnp.asarray([0.0, 0.0, 0.5 * thickness], centres.dtype)
    return box_pose_from_top(centres, normals, yaw, half)


# ------------------------------------------------------------------------------ fragility
def collapse_update(collapsed: Array, touch: Array, r_break: Array) -> Array:
    """Latched collapse of fragile footholds, (F,) bool: a pad collapses as soon as its touch
    reading (F,) [N] exceeds its breaking load r_break (F,) [N], and stays collapsed."""
    return jnp.logical_or(collapsed, touch > r_break)


def drop_away(pos: Array, quat: Array, collapsed: Array, drop: float = 0.3) -> Array:
    """Positions (F, 3) [m] of fragile pads with the collapsed ones moved by `drop` [m] along
    minus their top-face normal (out of reach). Pass the intact poses (from `place`), not the
    already dropped ones: the result does not accumulate."""
    normal = quat_z_axis(quat)
    shift = jnp.where(collapsed, drop, 0.0).astype(pos.dtype)
    return pos - shift[..., None] * normal


# ------------------------------------------------------------------------------ structure
@dataclass(frozen=True)
class Piece:
    """One terrain piece: a mocap body with one box geom of half sizes `half_size` [m]."""

    name: str
    half_size: tuple[float, float, float]
    fragile: bool = False  # gets a touch sensor over its top face and may collapse


@dataclass(frozen=True)
class ArrayInput:
    """A non-scalar placement input (e.g. foothold centres), passed to `Terrain.place` by name.

    `default` is a nested tuple giving the default array; its shape is fixed."""

    name: str
    default: tuple[tuple[float, ...], ...]
    doc: str
    unit: str = ""

    @property
    def shape(self) -> tuple[int, ...]:
        return np.asarray(self.default, dtype=float).shape

    def check(self, value: Any) -> np.ndarray:
        """`value` as a float array of this input's shape with finite entries, or SpecError."""
        try:
            out = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise SpecError(f"{self.name}: expected an array of shape {self.shape}, got {value!r}") from None
        if out.shape != self.shape:
            raise SpecError(f"{self.name}: expected an array of shape {self.shape}, got shape {out.shape}")
        if not np.all(np.isfinite(out)):
            raise SpecError(f"{self.name}: expected finite values")
        return out


def _float(x: Any) -> Array:
    x = jnp.asarray(x)
    return x if jnp.issubdtype(x.dtype, jnp.floating) else x.astype(jnp.result_type(float))


@dataclass(frozen=True)
class Terrain:
    """A terrain: pieces (static) and a pure placement function.

    `place_fn(values, key)` gets every parameter (scalar params and array inputs, defaults
    filled) as JAX arrays and a PRNG key, and returns the world poses of the pieces' boxes:
    pos (P, 3) [m] and quat (P, 4) (w, x, y, z), in piece order.
    """

    kind: str
    pieces: tuple[Piece, ...]
    params: tuple[Param, ...]
    place_fn: PlaceFn
    arrays: tuple[ArrayInput, ...] = ()  # non-scalar inputs (footholds: centres, normals)

    def __post_init__(self) -> None:
        names = [p.name for p in self.pieces]
        if len(set(names)) != len(names):
            raise ValueError(f"terrain {self.kind}: duplicate piece names")
        inputs = [p.name for p in self.params] + [a.name for a in self.arrays]
        if len(set(inputs)) != len(inputs):
            raise ValueError(f"terrain {self.kind}: duplicate parameter names")

    # ---------------------------------------------------------------- parameters
    def input_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params) + tuple(a.name for a in self.arrays)

    def defaults(self) -> dict[str, Any]:
        """Default value of every parameter and array input."""
        out: dict[str, Any] = {p.name: p.default for p in self.params}
        out.update({a.name: np.asarray(a.default, dtype=float) for a in self.arrays})
        return out

    def _check_names(self, values: Mapping[str, Any]) -> None:
        known = self.input_names()
        for name in values:
            if name not in known:
                listed = ", ".join(known) or "none"
                raise SpecError(f"{name}: unknown parameter for terrain '{self.kind}' (known: {listed})")

    def check(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """Validated values with defaults filled: scalar params as Python floats (Param.check),
        array inputs as float arrays of their fixed shape. SpecError (one line, naming the
        parameter and its allowed range) for an unknown name or a bad value."""
        self._check_names(values)
        out: dict[str, Any] = {}
        for p in self.params:
            value = values.get(p.name, p.default)
            if isinstance(value, np.generic | np.ndarray) and np.ndim(value) == 0:
                value = value.item()
            out[p.name] = p.check(value)
        for a in self.arrays:
            out[a.name] = a.check(values.get(a.name, a.default))
        return out

    def place(self, values: Mapping[str, Any] | None = None, key: Array | None = None) -> tuple[Array, Array]:
        """World poses of the pieces: pos (P, 3) [m], quat (P, 4) (w, x, y, z).

        `values` maps parameter names to numbers or JAX arrays (missing ones take their
        defaults; an unknown name raises SpecError, ranges are not checked here: use `check`).
        `key` is the PRNG key of random terrains (default PRNGKey(0)). Pure: jit it, vmap it
        over `values` (a dict of arrays) and `key`, differentiate it w.r.t. the values.
        """
        values = {} if values is None else values
        self._check_names(values)
        full = {name: _float(values.get(name, default)) for name, default in self.defaults().items()}
        if key is None:
            key = jax.random.PRNGKey(0)
        return self.place_fn(full, key)

    # ---------------------------------------------------------------- structure
    @property
    def fragile_mask(self) -> np.ndarray:
        """(P,) bool: which pieces are fragile."""
        return np.array([p.fragile for p in self.pieces], dtype=bool)

    def body_names(self, prefix: str = "terrain") -> tuple[str, ...]:
        """Names of the pieces' mocap bodies (and of their geoms), in piece order."""
        return tuple(f"{prefix}/{p.name}" for p in self.pieces)

    def touch_sensor_names(self, prefix: str = "terrain") -> tuple[str, ...]:
        """Names of the touch sensors (and of their sites) of the fragile pieces, in piece order."""
        return tuple(f"{prefix}/{p.name}/touch" for p in self.pieces if p.fragile)

    def add_to(
        self,
        spec: mujoco.MjSpec,
        prefix: str = "terrain",
        friction: tuple[float, float, float] = (1.0, 0.005, 0.0001),
        rgba: tuple[float, float, float, float] | None = None,
    ) -> None:
        """Add the pieces to `spec.worldbody` as mocap bodies at the default placement.

        Body and geom of piece p are named f"{prefix}/{p.name}"; the geom is a box (condim 3,
        `friction` = sliding, torsional, rolling) filtered with TERRAIN_CONTYPE/CONAFFINITY.
        A fragile piece also gets a thin box site f"{prefix}/{p.name}/touch" covering its top
        face and a touch sensor of the same name. `rgba` None: grey, fragile pieces orange.
        Mocap ids follow the order of addition; use `mocap_ids` after compiling.
        """
        pos, quat = self.place()
        pos, quat = np.asarray(pos, dtype=float), np.asarray(quat, dtype=float)
        for i, (piece, name) in enumerate(zip(self.pieces, self.body_names(prefix), strict=True)):
            body = spec.worldbody.add_body(name=name, mocap=True, pos=pos[i].tolist(), quat=quat[i].tolist())
            colour = rgba if rgba is not None else (FRAGILE_RGBA if piece.fragile else DEFAULT_RGBA)
            geom = body.add_geom(
                name=name,
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=list(piece.half_size),
                contype=TERRAIN_CONTYPE,
                conaffinity=TERRAIN_CONAFFINITY,
                condim=3,
                friction=list(friction),
                rgba=list(colour),
            )
            if piece.fragile:
                t = TOUCH_HALF_THICKNESS + geom.margin
                hx, hy, hz = piece.half_size
                site_name = f"{name}/touch"
                body.add_site(
                    name=site_name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[hx + t, hy + t, t], pos=[0.0, 0.0, hz],
                    rgba=[1.0, 0.0, 0.0, 0.0],
                )
                spec.add_sensor(
                    name=site_name, type=mujoco.mjtSensor.mjSENS_TOUCH, objtype=mujoco.mjtObj.mjOBJ_SITE,
                    objname=site_name,
                )


def mocap_ids(model: mujoco.MjModel, terrain: Terrain, prefix: str = "terrain") -> np.ndarray:
    """Rows of `mocap_pos`/`mocap_quat` holding the terrain's pieces, (P,) int, piece order."""
    ids = np.array([model.body(name).mocapid[0] for name in terrain.body_names(prefix)], dtype=int)
    if np.any(ids < 0):
        raise ValueError(f"terrain {terrain.kind}: some bodies with prefix '{prefix}' are not mocap bodies")
    return ids


# ------------------------------------------------------------------------------ parameters
THETA = Param("theta", 0.0, "slope inclination", "rad", lo=-HALF_PI, hi=HALF_PI, lo_open=True, hi_open=True)
DIRECTION = Param("direction", 0.0, "azimuth of the uphill gradient from world +x", "rad", lo=-TWO_PI, hi=TWO_PI)


def _stack_one(pos: Array, quat: Array) -> tuple[Array, Array]:
    return pos[None], quat[None]


def _grid(count: int, spacing: Array) -> Array:
    """Offsets (count,) of `count` points `spacing` apart centred on 0."""
    return (jnp.arange(count) - 0.5 * (count - 1)) * spacing


# ------------------------------------------------------------------------------ factories
def flat(half_extent: float = 10.0, half_depth: float = 0.5) -> Terrain:
    """Flat ground: one box (2 half_extent square) whose top face is at z = `height` (default 0)."""
    half = (half_extent, half_extent, half_depth)

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        h = v["height"]
        pos = jnp.stack([jnp.zeros_like(h), jnp.zeros_like(h), h - half_depth])
        return _stack_one(pos, quat_z(jnp.zeros_like(h)))

    params = (Param("height", 0.0, "height of the ground's top face", "m", lo=-100.0, hi=100.0),)
    return Terrain("flat", (Piece("ground", half),), params, place_fn)


def slope(half_length: float = 5.0, half_width: float = 5.0, half_depth: float = 0.5) -> Terrain:
    """A uniform slope: one box (2 half_length along the gradient, 2 half_width across) whose top
    face is the plane through the origin with inclination `theta` and uphill azimuth `direction`
    (both default 0: flat)."""
    half = (half_length, half_width, half_depth)

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        theta, direction = v["theta"], v["direction"]
        n = slope_normal(theta, direction)
        return _stack_one(*box_pose_from_top(jnp.zeros_like(n), n, direction, jnp.asarray(half)))

    return Terrain("slope", (Piece("ground", half),), (THETA, DIRECTION), place_fn)


def irregular_slope(rows: int = 4, cols: int = 4, tile: float = 0.25, half_depth: float = 0.25) -> Terrain:
    """The leg-grope paper's irregular slope: rows x cols square tiles of side `tile` [m] on the
    mean slope (theta, direction), all with inclination theta; tile k's uphill azimuth is
    direction + spread * u_k, u_k ~ U(-1, 1) from the PRNG key (spread default 0: a plain slope).

    Tiles sit on a grid in slope-frame coordinates centred on the origin (rows along the uphill
    gradient, cols across); each tile's top-face centre lies on the mean plane. Piece k =
    r * cols + c is named f"tile{r}_{c}"."""
    half = (0.5 * tile, 0.5 * tile, half_depth)
    pieces = tuple(Piece(f"tile{r}_{c}", half) for r in range(rows) for c in range(cols))

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        theta, direction, spread = v["theta"], v["direction"], v["spread"]
        dtype = jnp.result_type(theta, direction, spread)
        u = jax.random.uniform(key, (rows * cols,), dtype, -1.0, 1.0)
        normals = slope_normal(theta, direction + spread * u)
        uphill, across = slope_axes(theta, direction)
        a = jnp.repeat(_grid(rows, tile), cols)
        b = jnp.tile(_grid(cols, tile), rows)
        tops = a[:, None] * uphill + b[:, None] * across
        yaw = jnp.broadcast_to(direction, (rows * cols,))
        return box_pose_from_top(tops, normals, yaw, jnp.asarray(half))

    spread = Param("spread", 0.0, "tile gradient azimuths scatter uniformly within +- spread", "rad", lo=0.0,
                   hi=math.pi)
    return Terrain("irregular_slope", pieces, (THETA, DIRECTION, spread), place_fn)


def steps(
    n_terraces: int = 2,
    depth: float = 0.4,
    half_width: float = 1.0,
    max_height: float = 0.5,
    last_length: float = 5.0,
    floor_length: float = 5.0,
) -> Terrain:
    """A staircase climbing along +x with independent left (y in [0, half_width]) and right
    (y in [-half_width, 0]) columns.

    Params: `height_left`, `height_right` (total rise, [0, max_height], default 0.2 m) and
    `start` (x of the first riser, default 0.5 m). Terrace k (0-based) of a side spans x in
    [start + k depth, start + (k+1) depth] (the last one `last_length` long) with its top at
    height_side (k+1) / n_terraces. A floor box (top at z = 0) covers x in
    [start - floor_length, start], |y| <= half_width. Pieces: "floor", "left{k}", "right{k}".
    """
    hz = 0.5 * max_height + 0.1  # every terrace reaches down to z <= -0.2
    floor_hz = 0.25
    col = 0.5 * half_width
    sizes = [0.5 * depth] * (n_terraces - 1) + [0.5 * last_length]
    pieces = [Piece("floor", (0.5 * floor_length, half_width, floor_hz))]
    for side in ("left", "right"):
        pieces += [Piece(f"{side}{k}", (sizes[k], col, hz)) for k in range(n_terraces)]
    x_rel = np.array([k * depth + sizes[k] for k in range(n_terraces)])
    frac = np.arange(1, n_terraces + 1) / n_terraces

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        start = v["start"]
        floor = jnp.stack([start - 0.5 * floor_length, jnp.zeros_like(start), jnp.full_like(start, -floor_hz)])
        rows = [floor[None]]
        for sign, h in ((1.0, v["height_left"]), (-1.0, v["height_right"])):
            x = start + jnp.asarray(x_rel, start.dtype)
            z = h * jnp.asarray(frac, h.dtype) - hz
            y = jnp.full_like(x, sign * col)
            rows.append(jnp.stack([x, y, z], -1))
        pos = jnp.concatenate(rows)
        return pos, quat_z(jnp.zeros(pos.shape[0], pos.dtype))

    params = (
        Param("height_left", 0.2, "total rise of the left (y > 0) staircase", "m", lo=0.0, hi=max_height),
        Param("height_right", 0.2, "total rise of the right (y < 0) staircase", "m", lo=0.0, hi=max_height),
        Param("start", 0.5, "x of the first riser", "m", lo=-10.0, hi=10.0),
    )
    return Terrain("steps", tuple(pieces), params, place_fn)


def blocks(
    n: int = 1, half_size: tuple[float, float, float] = (0.25, 0.25, 0.5), floor_half_extent: float = 5.0
) -> Terrain:
    """n boxes standing on flat ground (a floor box, top at z = 0, 2 floor_half_extent square).

    Params per block i: `block{i}_x`, `block{i}_y` (centre [m], defaults 1 + i, 0), `block{i}_height`
    (protrusion of its top above the ground, [0, 2 half_size_z], default min(0.1, 2 half_size_z))
    and `block{i}_yaw` (rad about z, default 0). Pieces: "floor", "block{i}"."""
    floor_hz = 0.25
    hz = half_size[2]
    pieces = (Piece("floor", (floor_half_extent, floor_half_extent, floor_hz)),) + tuple(
        Piece(f"block{i}", tuple(half_size)) for i in range(n)
    )
    lim = floor_half_extent
    params: list[Param] = []
    for i in range(n):
        params += [
            Param(f"block{i}_x", 1.0 + i, f"x of block {i}'s centre", "m", lo=-lim, hi=lim),
            Param(f"block{i}_y", 0.0, f"y of block {i}'s centre", "m", lo=-lim, hi=lim),
            Param(f"block{i}_height", min(0.1, 2 * hz), f"protrusion of block {i} above the ground", "m", lo=0.0,
                  hi=2 * hz),
            Param(f"block{i}_yaw", 0.0, f"yaw of block {i} about z", "rad", lo=-TWO_PI, hi=TWO_PI),
        ]

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        x = jnp.stack([v[f"block{i}_x"] for i in range(n)])
        y = jnp.stack([v[f"block{i}_y"] for i in range(n)])
        z = jnp.stack([v[f"block{i}_height"] for i in range(n)]) - hz
        yaw = jnp.stack([v[f"block{i}_yaw"] for i in range(n)])
        floor = jnp.zeros((1, 3), x.dtype).at[0, 2].set(-floor_hz)
        pos = jnp.concatenate([floor, jnp.stack([x, y, z], -1)])
        quat = jnp.concatenate([quat_z(jnp.zeros((1,), x.dtype)), quat_z(yaw)])
        return pos, quat

    return Terrain("blocks", pieces, tuple(params), place_fn)


def frames_on_slope(
    nx: int = 4,
    ny: int = 4,
    beam_width: float = 0.2,
    max_spacing: float = 1.5,
    max_beam_height: float = 0.3,
    half_length: float = 5.0,
    half_width: float = 5.0,
) -> Terrain:
    """A grid of concrete frame beams on a slope (slope-protection frames).

    `nx` beams run along the uphill gradient ("along{i}", spaced across the slope) and `ny`
    across it ("across{j}", spaced along the gradient), centred on the origin in slope-frame
    coordinates, plus the slope box ("slope", as `slope(half_length, half_width)`). Params:
    `theta`, `direction` (as `slope`), `spacing` (beam centre distance, [beam_width, max_spacing],
    default 1 m) and `beam_height` (protrusion of the beam tops above the slope plane, measured
    along its normal, [0, max_beam_height], default 0.15 m). Beam lengths are fixed for
    max_spacing, so at smaller spacings the beams overhang the outermost crossings.
    """
    hzb = 0.5 * max_beam_height + 0.05  # beams reach >= 0.1 m below the slope plane
    slope_half = (half_length, half_width, 0.5)
    along_half = (0.5 * ((ny - 1) * max_spacing + beam_width), 0.5 * beam_width, hzb)
    across_half = (0.5 * beam_width, 0.5 * ((nx - 1) * max_spacing + beam_width), hzb)
    pieces = (
        (Piece("slope", slope_half),)
        + tuple(Piece(f"along{i}", along_half) for i in range(nx))
        + tuple(Piece(f"across{j}", across_half) for j in range(ny))
    )
    halves = np.array([slope_half] + [along_half] * nx + [across_half] * ny)

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        theta, direction, spacing, h = v["theta"], v["direction"], v["spacing"], v["beam_height"]
        n = slope_normal(theta, direction)
        uphill, across = slope_axes(theta, direction)
        along_tops = h * n + _grid(nx, spacing)[:, None] * across
        across_tops = h * n + _grid(ny, spacing)[:, None] * uphill
        tops = jnp.concatenate([jnp.zeros_like(n)[None], along_tops, across_tops])
        count = 1 + nx + ny
        normals = jnp.broadcast_to(n, (count, 3))
        yaw = jnp.broadcast_to(direction, (count,))
        return box_pose_from_top(tops, normals, yaw, jnp.asarray(halves, tops.dtype))

    params = (
        THETA,
        DIRECTION,
        Param("spacing", 1.0, "distance between neighbouring beam centres", "m", lo=beam_width, hi=max_spacing),
        Param("beam_height", 0.15, "protrusion of the beam tops above the slope plane", "m", lo=0.0,
              hi=max_beam_height),
    )
    return Terrain("frames_on_slope", pieces, params, place_fn)


def footholds(n: int, half_size: float = 0.03, thickness: float = 0.02, spacing: float = 0.2) -> Terrain:
    """n fragile square pads ("pad{i}", side 2 half_size, `thickness` [m]) with touch sensors.

    No scalar params: placement comes from the array inputs `centres` (n, 3) [m] (top-face
    centres, default (spacing i, 0, 0)) and `normals` (n, 3) (outward top-face normals, default
    +z), e.g. `terrain.place({"centres": c, "normals": nrm})`; see `pad_poses`."""
    pieces = tuple(Piece(f"pad{i}", (half_size, half_size, 0.5 * thickness), fragile=True) for i in range(n))
    arrays = (
        ArrayInput("centres", tuple((spacing * i, 0.0, 0.0) for i in range(n)), "top-face centres of the pads",
                   "m"),
        ArrayInput("normals", tuple((0.0, 0.0, 1.0) for _ in range(n)), "outward top-face normals of the pads"),
    )

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        return pad_poses(v["centres"], v["normals"], thickness)

    return Terrain("footholds", pieces, (), place_fn, arrays)


# ------------------------------------------------------------------------------ combining
def _param_signature(p: Param) -> tuple[Any, ...]:
    return (p.default, p.unit, p.kind, p.lo, p.hi, p.lo_open, p.hi_open, p.choices, p.sweepable)


def combine(*terrains: Terrain) -> Terrain:
    """One terrain made of all the parts' pieces (part i's piece p renamed f"{kind}{i}/{p}") and
    parameters. A parameter name used by several parts is shared (one value drives all) if its
    default and range agree, else ValueError. Every part is placed with the same PRNG key, so
    the combined placement is the concatenation of the parts' placements."""
    if not terrains:
        raise ValueError("combine needs at least one terrain")
    pieces = tuple(
        replace(p, name=f"{t.kind}{i}/{p.name}") for i, t in enumerate(terrains) for p in t.pieces
    )
    params: dict[str, Param] = {}
    arrays: dict[str, ArrayInput] = {}
    for t in terrains:
        for p in t.params:
            if p.name in params and _param_signature(params[p.name]) != _param_signature(p):
                raise ValueError(f"combine: parameter '{p.name}' has different defaults or ranges in two parts")
            params.setdefault(p.name, p)
        for a in t.arrays:
            if a.name in arrays and (arrays[a.name].default, arrays[a.name].unit) != (a.default, a.unit):
                raise ValueError(f"combine: array input '{a.name}' has different defaults in two parts")
            arrays.setdefault(a.name, a)
    clash = set(params) & set(arrays)
    if clash:
        raise ValueError(f"combine: {', '.join(sorted(clash))} is both a parameter and an array input")
    parts = tuple(terrains)

    def place_fn(v: dict[str, Array], key: Array) -> tuple[Array, Array]:
        placed = [t.place_fn(v, key) for t in parts]
        return jnp.concatenate([p for p, _ in placed]), jnp.concatenate([q for _, q in placed])

    kind = "+".join(t.kind for t in terrains)
    return Terrain(kind, pieces, tuple(params.values()), place_fn, tuple(arrays.values()))
