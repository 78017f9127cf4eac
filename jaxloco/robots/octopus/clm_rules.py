"""The control rules of OCTOPUS's compound locomotion mode (CLM), each a pure JAX function
of the last sampling period's measurements (paper, "Control system design for CLM").
The CLM controller composes them at 50 Hz; here every rule is separate so that it can be
tested against its closed form, vmapped over a batch and differentiated.

Angle conventions are the model's (`params.py`, `model.py`):
  * flipper angle A [rad], 0 in line with the main crawler, > 0 lifts the tip; flipper
    torque T [N m] is the servo's torque on the flipper, > 0 lifting;
  * arm joints (theta_1 swing, theta_2 boom, theta_3 elbow) [rad]: theta_2 > 0 and
    theta_3 > 0 turn boom and forearm downwards (Eq. 28 lowers the booms by +Delta_E
    to push the body up);
  * points in the robot frame {R} [m]; attitude (R_P, T_P) as in `kinematics` (> 0 nose
    up).

Where the text's signs cannot hold together (conversion typos, and the arm angle
constants quoted for the authors' own joint zero), the physically consistent reading is
used and said next to each rule.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

Array = jax.Array

# flipper rule cases
FLIPPER_HOLD, FLIPPER_FOLLOW, FLIPPER_LIMIT = 0, 1, 2
# arm stop cases (after a transfer)
STOP_REACHED, STOP_BLOCKED, STOP_ON_OBSTACLE, STOP_IN_PIT = 0, 1, 2, 3
STOP_NAMES = ("reached", "obstacle before the target", "obstacle on the target", "pit at the target")
# arm transfer phases (Eqs. 19-21)
LIFT, SWING, OVER, LOWER, PLACED = 0, 1, 2, 3, 4
TRANSFER_PHASES = ("lift", "swing", "over", "lower", "placed")
# the crawl gait of the arms (Fig. 7 is missing): one arm at a time, rear before front on
# each side, so that at least three arms always support the robot (the text) and the
# paper's joint plot (Fig. 14) sees RR transfer, then RF. Arm indices 0..3 = arms 1..4
# (LF, RF, LR, RR).
CRAWL_ORDER = (3, 1, 2, 0)  # RR, RF, LR, LF


def flipper_rule(a_prev: Array, t_prev: Array, t0: Array, delta_a: Array, a0: Array, delta_b: Array
                 ) -> tuple[Array, Array]:
    """Front flipper command A for the next period and the case that chose it.

    Case 1 |T'| < T0: A = A' (vibration on flat ground); Case 2 |T'| >= T0:
    A = A' - Delta_A sign(T') (the flipper yields to the terrain: an obstacle pushes the
    tip up, the servo answers with a negative torque, and the flipper turns up; a pit
    lets it turn down); Case 3 A' > A0 (at the limit): A = A' - Delta_B, and the CLM
    reads it as an obstacle ahead. Case 3 takes precedence. Shapes broadcast (e.g. (2,)
    for both front flippers)."""
    follow = jnp.abs(t_prev) >= t0
    limit = a_prev > a0
    a = jnp.where(follow, a_prev - delta_a * jnp.sign(t_prev), a_prev)
    a = jnp.where(limit, a_prev - delta_b, a)
    case = jnp.where(limit, FLIPPER_LIMIT, jnp.where(follow, FLIPPER_FOLLOW, FLIPPER_HOLD)).astype(jnp.int32)
    return a, case


def arm_stop_case(actual: Array, target: Array, delta_c: Array, delta_d: Array) -> Array:
    """Where a transferred arm stopped (paper, "Arm stop", Cases 1-3), from the EPRA's
    actual stop point and its target ({R}, (..., 3) [m]): STOP_BLOCKED if |dx| > Delta_C
    (something between the arm and its target), else STOP_ON_OBSTACLE if dz > Delta_D,
    STOP_IN_PIT if dz < -Delta_D, STOP_REACHED otherwise."""
    dx = actual[..., 0] - target[..., 0]
    dz = actual[..., 2] - target[..., 2]
    case = jnp.where(dz > delta_d, STOP_ON_OBSTACLE, jnp.where(dz < -delta_d, STOP_IN_PIT, STOP_REACHED))
    return jnp.where(jnp.abs(dx) > delta_c, STOP_BLOCKED, case).astype(jnp.int32)


def collision(torque: Array, torque_prev: Array, threshold: Array) -> Array:
    """Torque-based collision signal of an arm (paper: "the torque of related joints will
    increase in a short time"): True where any joint's torque rose by more than
    `threshold` [N m] in one period. torque, torque_prev (..., 3)."""
    return jnp.any(jnp.abs(torque) - jnp.abs(torque_prev) > threshold, axis=-1)


def predict_contacts(points: Array, step: Array, terrain_pitch: Array, robot_pitch: Array) -> Array:
    """Contact points of the arms in {R} one sampling period later (Eqs. 22-27), for a
    crawler travel `step` [m]: points (..., 3) -> (..., 3).

    Reading: the arms hold their contact points fixed on the ground ("to minimize the
    mobile range of contact points"), and the crawlers carry the body a distance L along
    the terrain, which is inclined by T_P - R_P against x_R. A ground-fixed point then
    moves by -L (cos(T_P - R_P), 0, sin(T_P - R_P)) in {R}, for front and rear arms
    alike. The printed Eqs. 22-27 give +L cos for the rear arms' x and -L sin for the
    front arms' x, and +L sin for z: signs and sin/cos that no rigid motion produces
    (the front and rear contacts would move apart along x), which we take for
    conversion typos; the dependence on T_P - R_P and y unchanged (Eqs. 23, 26) are kept."""
    alpha = terrain_pitch - robot_pitch
    shift = jnp.stack([jnp.cos(alpha), jnp.zeros_like(alpha), jnp.sin(alpha)], axis=-1)
    return points - jnp.asarray(step)[..., None] * shift


def transfer_step(
    q_prev: Array,
    phase: Array,
    contact: Array,
    q_target: Array,
    q_above: Array,
    lift_boom: Array,
    k: Array,
    delta_a: Array,
    delta_b: Array,
    tol: Array = 0.02,
) -> tuple[Array, Array]:
    """One period of an arm transfer (Eqs. 19-21): joint commands (3,) and the next phase.

    LIFT:  the boom turns up towards `lift_boom` (theta_2 <- theta_2' + K (A_B - theta_2')),
           the elbow folds (theta_3' - Delta_B), the swing holds; done when theta_2' is
           within `tol` of A_B;
    SWING: the swing turns by Delta_A per period towards the target's swing angle A_S
           (boom and elbow hold); done within Delta_A of it;
    OVER, LOWER (the paper's "down arm" period): boom and elbow turn towards the angles
           `q_above` that put the EPRA above the target, then towards the target's
           angles `q_target` (K of the way per period, at least Delta_B on the larger
           change, never past them), then the boom goes on down by Delta_B per period
           until `contact` (the collision or contact signal), then PLACED. Passing
           above the target first makes the last part of the descent nearly vertical:
           going straight for the target's angles from the lifted pose swept the EPRA
           up to 70 mm past the target before it touched (tests).
    The text's constants (A_B = +-0.6, A_S = 1.16 / -0.65 rad) are for the authors' joint
    zeros and are not reproducible in our frames (`params.py`): A_B = `lift_boom` and A_S
    = q_target[0] (from inverse kinematics to the Table 2 target) are inputs here. Eq.
    20 is printed as theta_2' - K (0.6 - theta_2') in LIFT: read as a proportional step
    of gain K towards A_B."""
    q_prev = jnp.asarray(q_prev)
    lift = q_prev.at[1].add(k * (lift_boom - q_prev[1])).at[2].add(-delta_b)
    lifted = jnp.abs(q_prev[1] - lift_boom) < tol
    dswing = q_target[0] - q_prev[0]
    swing = q_prev.at[0].add(jnp.clip(dswing, -delta_a, delta_a))
    swung = jnp.abs(dswing) <= delta_a

    def towards(goal):
        remaining = goal[1:] - q_prev[1:]
        largest = jnp.max(jnp.abs(remaining))
        frac = jnp.minimum(1.0, jnp.maximum(k, delta_b / jnp.where(largest > 0, largest, 1.0)))
        return q_prev.at[1:].add(frac * remaining), largest < 1e-9

    over, above = towards(q_above)
    lower, at_target = towards(q_target)
    lower = jnp.where(at_target, q_prev.at[1].add(delta_b), lower)
    cmd = jnp.select([phase == LIFT, phase == SWING, phase == OVER, phase == LOWER], [lift, swing, over, lower],
                     q_prev)
    nxt = jnp.select(
        [(phase == LIFT) & lifted, (phase == SWING) & swung, (phase == OVER) & (above | contact),
         (phase == LOWER) & contact],
        [SWING, OVER, LOWER, PLACED],
        phase,
    ).astype(jnp.int32)
    return cmd, nxt


def climb_rule(boom_prev: Array, flipper_prev: Array, cog_height: Array, step_height: Array, travelled: Array,
               settle_distance: Array, delta_e: Array, delta_f: Array) -> tuple[Array, Array, Array]:
    """Step climbing (Eqs. 28-29): boom angles (...,) and flipper angles (...,) for the next
    period, and whether the robot is on top (released).

    While H < H_EST or S < L (L = 0.3 m, 0.6 of the 500 mm body): booms +Delta_E (down,
    lifting the body) and flippers -Delta_F (down); once H > H_EST and S > L: booms
    -Delta_E while theta_2' > 0 and flippers +Delta_F while A' < 0 (release, Fig. 9f-h)."""
    climbing = jnp.less(cog_height, step_height) | jnp.less(travelled, settle_distance)
    boom = jnp.where(climbing, boom_prev + delta_e, jnp.where(boom_prev > 0, boom_prev - delta_e, boom_prev))
    flip = jnp.where(climbing, flipper_prev - delta_f,
                     jnp.where(flipper_prev < 0, flipper_prev + delta_f, flipper_prev))
    return boom, flip, ~climbing
