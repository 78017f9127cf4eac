"""Grid maps for the TITAN XI gait (Hodoshima et al. 2007, Section 8.2.1): an unevenness
grid map (surface height per cell) and a forbidden-foothold grid map (frames and
unevenness too large for a foot pad), on fixed-shape arrays so that map generation and
planning vmap over maps and over frame parameters.

Frame: the map frame (see `params`): x, y in the base plane, z normal to it. On the
Section 8.4 slope the map frame is the slope frame: x up the fall line, y across the
slope, z normal to the slope; heights are measured along that normal (0 on the mortar
surface, the frame height on the frames). `GridMap.slope` keeps the slope angle so that
`map_to_world` can express points in the world frame (z up), and the gait can build the
effective gravity when the tethers do not cancel the slope-parallel component.

Cells: cell (i, j) (i along x, j along y) has its centre at origin + (i + 1/2, j + 1/2)
cell. Points are looked up in their nearest cell; points outside the map read as
forbidden with height 0.

Forbidden cells are conservative for a foot pad of radius r centred anywhere in the
cell: a cell is forbidden when a frame edge is within r + cell / sqrt(2) of its centre
(the farthest a point of the cell is from its centre), so a foot placed at any point of a
free cell keeps its whole pad off the frames.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from jaxloco import geometry as geo
from jaxloco.robots.titan import params

Array = jax.Array


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class GridMap:
    """Unevenness and forbidden-foothold grid maps on the same grid (map frame)."""

    height: Array  # (NX, NY) surface height [m]
    forbidden: Array  # (NX, NY) bool
    origin: Array  # (2,) xy of the outer corner of cell (0, 0) [m]
    cell: Array  # () cell size [m]
    slope: Array  # () slope angle of the map frame about the world y axis [rad]


def cell_centres(shape: tuple[int, int], origin: Array, cell: Array) -> Array:
    """(NX, NY, 2) xy of the cell centres."""
    i = jnp.arange(shape[0], dtype=jnp.asarray(cell).dtype)
    j = jnp.arange(shape[1], dtype=jnp.asarray(cell).dtype)
    x = origin[0] + (i + 0.5) * cell
    y = origin[1] + (j + 0.5) * cell
    return jnp.stack(jnp.meshgrid(x, y, indexing="ij"), axis=-1)


def _index(gmap: GridMap, xy: Array) -> tuple[Array, Array, Array]:
    """Nearest cell (i, j) of points xy (..., 2) and whether it is inside the map."""
    # + 1e-6 cell: points on a cell boundary (round numbers are common: I_u, strokes) go to
    # the upper cell whatever the rounding of the arithmetic that produced them, so jit,
    # vmap and eager give the same cell
    ij = jnp.floor((xy - gmap.origin) / gmap.cell + 1e-6).astype(jnp.int32)
    nx, ny = gmap.height.shape
    inside = (
        (ij[..., 0] >= 0) & (ij[..., 0] < nx) & (ij[..., 1] >= 0) & (ij[..., 1] < ny)
    )
    i = jnp.clip(ij[..., 0], 0, nx - 1)
    j = jnp.clip(ij[..., 1], 0, ny - 1)
    return i, j, inside


def sample_height(gmap: GridMap, xy: Array) -> Array:
    """Height of the cell under each point xy (..., 2) (Sec. 6.2: "the height on the map at
    the position"); 0 outside the map."""
    i, j, inside = _index(gmap, xy)
    return jnp.where(inside, gmap.height[i, j], 0.0)


def sample_forbidden(gmap: GridMap, xy: Array) -> Array:
    """Whether each point xy (..., 2) is an unsuitable foothold (outside the map: yes)."""
    i, j, inside = _index(gmap, xy)
    return ~inside | gmap.forbidden[i, j]


def map_to_world(gmap: GridMap, p: Array) -> Array:
    """Points (..., 3) from the map frame to the world frame (z up): rotation by the slope
    angle about y, so map x points up the fall line."""
    return p @ geo.rot_y(-gmap.slope).T


def _shift(a: Array, di: int, dj: int, fill) -> Array:
    """a shifted so that out[i, j] = a[i + di, j + dj] (fill outside)."""
    nx, ny = a.shape
    p = jnp.pad(a, ((abs(di), abs(di)), (abs(dj), abs(dj))), constant_values=fill)
    return p[abs(di) + di : abs(di) + di + nx, abs(dj) + dj : abs(dj) + dj + ny]


def height_range(
    height: Array, cell: Array, radius: Array, max_cells: int = 3
) -> Array:
    """max - min of the height over the cells whose centres are within `radius` of each
    cell centre (the foot pad), with at most `max_cells` cells each way (static)."""
    hi = height
    lo = height
    for di in range(-max_cells, max_cells + 1):
        for dj in range(-max_cells, max_cells + 1):
            if di == 0 and dj == 0:
                continue
            use = math.hypot(di, dj) * cell <= radius
            hi = jnp.where(use, jnp.maximum(hi, _shift(height, di, dj, -jnp.inf)), hi)
            lo = jnp.where(use, jnp.minimum(lo, _shift(height, di, dj, jnp.inf)), lo)
    r = hi - lo
    return jnp.where(jnp.isfinite(r), r, 0.0)


def forbidden_map(
    frame_distance: Array,
    ground: Array,
    cell: Array,
    foot_radius: Array,
    uneven_max: Array = params.UNEVEN_MAX,
) -> Array:
    """Forbidden-foothold map (Sec. 8.2.1 step 4): frames within the foot pad radius of any
    point of the cell (`frame_distance` is the distance from the cell centre to the nearest
    frame edge, <= 0 on a frame) or ground unevenness under the pad above `uneven_max`."""
    near_frame = frame_distance <= foot_radius + cell * (0.5 * math.sqrt(2.0))
    uneven = height_range(ground, cell, foot_radius + cell) > uneven_max
    return near_frame | uneven


FACE_TOLERANCE = 1e-9  # [m] a cell centre this close to a frame's face is on it


def _periodic_distance(x: Array, offset: Array, interval: Array) -> Array:
    """Distance from x to the nearest line of the family offset + k interval."""
    u = jnp.mod(x - offset, interval)
    return jnp.minimum(u, interval - u)


def frame_distance(
    c: Array, frame_size: Array, interval: Array, offset: Array
) -> Array:
    """Signed distance [m] from the points c (..., 2) to the nearest face of a square grid
    of frames (section `frame_size`, centre lines x = ox + k interval, y = oy + k interval):
    <= 0 on a frame, +inf when frame_size = 0 (no frames)."""
    dx = _periodic_distance(c[..., 0], offset[0], interval)
    dy = _periodic_distance(c[..., 1], offset[1], interval)
    dist = jnp.minimum(dx, dy) - 0.5 * frame_size
    # a cell centre on a frame's face (the usual case: 0.1 m cells, 0.2 / 0.3 m frames on
    # whole-metre grids) is on the frame; snapping the rounding noise to 0 makes every
    # compiled form of this function (vmapped, jitted, optimised or not) decide it alike
    dist = jnp.where(jnp.abs(dist) <= FACE_TOLERANCE, 0.0, dist)
    return jnp.where(frame_size > 0, dist, jnp.inf)


def _frames_map(dist, size, cell, origin, slope, foot_radius, ground) -> GridMap:
    dtype = dist.dtype
    g = jnp.zeros(dist.shape, dtype) if ground is None else ground
    height = g + jnp.where(dist <= 0, size, 0.0)
    forb = forbidden_map(dist, g, cell, foot_radius)
    return GridMap(
        height, forb, origin, jnp.asarray(cell, dtype), jnp.asarray(slope, dtype)
    )


@functools.partial(jax.jit, static_argnames="shape")  # one program per map shape, not one per operation
def frame_grid_map(
    shape: tuple[int, int],
    origin: Array,
    cell: Array,
    frame_size: Array,
    interval: Array,
    frame_offset: Array | None = None,
    slope: Array = 0.0,
    foot_radius: Array = params.FOOT_RADIUS,
    ground: Array | None = None,
) -> GridMap:
    """Square grid of frames of square section `frame_size` (width = height) with centre
    lines x = ox + k interval and y = oy + k interval (Sec. 7: 0.2 / 0.3 m frames on 2.0 /
    3.0 m grids; Sec. 8.4: 0.2 m frames every 1.5 m on a 30 deg slope, `slope` in rad).
    `ground` (NX, NY) adds surface unevenness (default flat). Every argument but `shape`
    may be traced; `frame_size` = 0 gives flat ground without frames."""
    dtype = jnp.asarray(cell).dtype
    origin = jnp.asarray(origin, dtype)
    off = jnp.zeros(2, dtype) if frame_offset is None else jnp.asarray(frame_offset, dtype)
    dist = frame_distance(cell_centres(shape, origin, cell), frame_size, interval, off)
    return _frames_map(dist, frame_size, cell, origin, slope, foot_radius, ground)


def mixed_frame_map(
    shape: tuple[int, int],
    origin: Array,
    cell: Array,
    field_a: tuple[Array, Array, Array],
    field_b: tuple[Array, Array, Array],
    block: Array,
    slope: Array = 0.0,
    foot_radius: Array = params.FOOT_RADIUS,
) -> GridMap:
    """A field combining two frame grids (Sec. 7: "environments combining these
    conditions"): a checkerboard of square blocks of side `block` [m] (edges at
    k block from the map-frame origin), field A = (frame_size, interval, offset (2,)) in
    the blocks with an even (i + j), field B in the others (`frame_grid_map`'s arguments).
    `block` = 0 gives field A everywhere. The block layout is ours (the paper shows no
    combined field)."""
    dtype = jnp.asarray(cell).dtype
    origin = jnp.asarray(origin, dtype)
    c = cell_centres(shape, origin, cell)
    dist_a = frame_distance(c, field_a[0], field_a[1], jnp.asarray(field_a[2], dtype))
    dist_b = frame_distance(c, field_b[0], field_b[1], jnp.asarray(field_b[2], dtype))
    k = jnp.floor(c / jnp.where(block > 0, block, 1.0)).astype(jnp.int32)
    in_b = (block > 0) & ((k[..., 0] + k[..., 1]) % 2 == 1)
    dist = jnp.where(in_b, dist_b, dist_a)
    size = jnp.where(in_b, field_b[0], field_a[0])
    return _frames_map(dist, size, cell, origin, slope, foot_radius, None)


def flat_map(shape: tuple[int, int], origin: Array, cell: Array = params.CELL) -> GridMap:
    """Flat ground without frames (the analytic standard-gait check)."""
    return frame_grid_map(shape, origin, jnp.asarray(cell), 0.0, 1.0)


# ----------------------------------------------------------- map generation from survey
def survey_points(
    n_nodes: tuple[int, int],
    interval: Array,
    node_origin: Array,
    frame_height: Array,
    ground_fn=None,
    noise: Array = 0.0,
    key: Array | None = None,
) -> tuple[Array, Array]:
    """Synthetic total-station survey (Sec. 8.2.1 step 1): frame intersections (NI, NJ, 3)
    measured on top of the frames (corner cube on the frame at the centre-line crossing)
    and points near the centres of the areas enclosed by frames (NI-1, NJ-1, 3) measured
    on the ground. `ground_fn(xy) -> z` gives the ground (default flat); `noise` is the
    standard deviation of a Gaussian measurement error [m] (the TS is +-5 mm)."""
    node_origin = jnp.asarray(node_origin)
    dtype = node_origin.dtype
    ii = jnp.arange(n_nodes[0], dtype=dtype)
    jj = jnp.arange(n_nodes[1], dtype=dtype)
    nodes = node_origin + interval * jnp.stack(
        jnp.meshgrid(ii, jj, indexing="ij"), axis=-1
    )
    centres = 0.5 * (nodes[:-1, :-1] + nodes[1:, 1:])
    gf = (
        (lambda xy: jnp.zeros(xy.shape[:-1], dtype)) if ground_fn is None else ground_fn
    )
    top = jnp.concatenate([nodes, (gf(nodes) + frame_height)[..., None]], axis=-1)
    mid = jnp.concatenate([centres, gf(centres)[..., None]], axis=-1)
    if key is not None:
        k1, k2 = jax.random.split(key)
        top = top + noise * jax.random.normal(k1, top.shape, dtype)
        mid = mid + noise * jax.random.normal(k2, mid.shape, dtype)
    return top, mid


def _node_normals(nodes: Array) -> Array:
    """Unit normals (NI, NJ, 3) of local planes fitted (least squares) through each
    intersection and its 4-neighbours (Sec. 8.2.1 step 2: "normal vectors for local planes
    formed by measured points, defined as the frame height direction")."""
    _ni, _nj, _ = nodes.shape
    pad = jnp.pad(nodes, ((1, 1), (1, 1), (0, 0)), mode="edge")
    nb = jnp.stack(
        [pad[1:-1, 1:-1], pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]],
        axis=2,
    )  # (NI, NJ, 5, 3); edge copies repeat a point, harmless for least squares
    n, _ = jax.vmap(jax.vmap(geo.fit_plane))(nb)
    return n


def _triangle_interp(q: Array, a: Array, b: Array, c: Array) -> tuple[Array, Array]:
    """z at xy q on the plane through 3D points a, b, c, and the smallest barycentric
    coordinate of q (>= 0 inside the triangle)."""
    v0, v1, v2 = b[:2] - a[:2], c[:2] - a[:2], q - a[:2]
    det = geo.cross2(v0, v1)
    det = jnp.where(jnp.abs(det) > 0, det, 1.0)
    l1 = geo.cross2(v2, v1) / det
    l2 = geo.cross2(v0, v2) / det
    l0 = 1.0 - l1 - l2
    return l0 * a[2] + l1 * b[2] + l2 * c[2], jnp.minimum(l0, jnp.minimum(l1, l2))


def _segment_distance_2d(q: Array, a: Array, b: Array) -> Array:
    ab = b - a
    t = jnp.clip(jnp.dot(q - a, ab) / jnp.maximum(jnp.dot(ab, ab), 1e-12), 0.0, 1.0)
    return jnp.linalg.norm(q - (a + t * ab))


@functools.partial(jax.jit, static_argnames="shape")  # one program per map shape, not one per operation
def map_from_survey(
    nodes: Array,
    centres: Array,
    frame_width: Array,
    frame_height: Array,
    shape: tuple[int, int],
    origin: Array,
    cell: Array = params.CELL,
    foot_radius: Array = params.FOOT_RADIUS,
    slope: Array = 0.0,
) -> GridMap:
    """Unevenness and forbidden-foothold grid maps from surveyed points (Sec. 8.2.1):

    2. frames: centre lines connect neighbouring intersections; the frame base at each
       intersection is its measured top minus `frame_height` along the local-plane normal;
    3. ground: each area enclosed by frames is split into four triangles (its centre
       point and two neighbouring frame-base corners) and the ground height of a cell is
       the linear interpolation on the triangle containing its centre (cells outside the
       surveyed grid use the nearest area, extrapolated);
    4. height = ground, plus `frame_height` on the frames; forbidden = frames within the
       pad of any point of the cell, or unevenness under the pad (`forbidden_map`).

    The surveyed grid must be close to the map axes (areas are located by the mean
    spacing along x and y)."""
    dtype = nodes.dtype
    cell = jnp.asarray(cell, dtype)
    origin = jnp.asarray(origin, dtype)
    ni, nj, _ = nodes.shape
    base = nodes - frame_height * _node_normals(nodes)
    c = cell_centres(shape, origin, cell).reshape(-1, 2)
    n0 = base[0, 0, :2]
    sx = (base[-1, 0, 0] - base[0, 0, 0]) / (ni - 1)
    sy = (base[0, -1, 1] - base[0, 0, 1]) / (nj - 1)

    def ground_at(q):
        a = jnp.clip(jnp.floor((q[0] - n0[0]) / sx).astype(jnp.int32), 0, ni - 2)
        b = jnp.clip(jnp.floor((q[1] - n0[1]) / sy).astype(jnp.int32), 0, nj - 2)
        m = centres[a, b]
        c00, c10, c11, c01 = (
            base[a, b],
            base[a + 1, b],
            base[a + 1, b + 1],
            base[a, b + 1],
        )
        zs, ws = zip(
            *[
                _triangle_interp(q, m, p, r)
                for p, r in ((c00, c10), (c10, c11), (c11, c01), (c01, c00))
            ]
        )
        zs, ws = jnp.stack(zs), jnp.stack(ws)
        return zs[jnp.argmax(ws)]

    ground = jax.vmap(ground_at)(c)
    seg_a = jnp.concatenate(
        [base[:-1, :, :2].reshape(-1, 2), base[:, :-1, :2].reshape(-1, 2)]
    )
    seg_b = jnp.concatenate(
        [base[1:, :, :2].reshape(-1, 2), base[:, 1:, :2].reshape(-1, 2)]
    )
    d = jax.vmap(
        lambda q: jnp.min(jax.vmap(_segment_distance_2d, (None, 0, 0))(q, seg_a, seg_b))
    )(c)
    dist = (d - 0.5 * frame_width).reshape(shape)
    ground = ground.reshape(shape)
    height = ground + jnp.where(dist <= 0, frame_height, 0.0)
    forb = forbidden_map(dist, ground, cell, foot_radius)
    return GridMap(height, forb, origin, cell, jnp.asarray(slope, dtype))


# ------------------------------------------------------------------------- scenarios
def section7_map(
    shape: tuple[int, int],
    origin: Array,
    large: bool = False,
    offset: Array | None = None,
) -> GridMap:
    """Section 7 flat ground: 0.2 m frames on a 2.0 m grid (or 0.3 m on 3.0 m, `large`)."""
    size, grid = (
        (params.FRAME_LARGE, params.GRID_LARGE) if large else (params.FRAME_SMALL, params.GRID_SMALL)
    )
    return frame_grid_map(shape, origin, jnp.asarray(params.CELL), size, grid, offset)


def slope_map(
    shape: tuple[int, int], origin: Array, offset: Array | None = None
) -> GridMap:
    """Section 8.4 test slope: 30 deg, 0.2 m frames every 1.5 m, in the slope frame."""
    return frame_grid_map(
        shape,
        origin,
        jnp.asarray(params.CELL),
        params.SLOPE_FRAME,
        params.SLOPE_GRID,
        offset,
        params.SLOPE_ANGLE,
    )
