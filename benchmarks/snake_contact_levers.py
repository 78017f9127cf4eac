"""T² Snake-3: what sets the contact forces' trend with the head's height (Tables IV-V), in closed form.

    python benchmarks/snake_contact_levers.py [OVERSHOOT_MM]

The paper's f_x and f_y both scale about as z_h^-2 over (i)-(iii) and (iv)-(vi), the law
of a push resisted by a rotational spring whose axis lies at a height h0 below the
contact: the lever is z_h - h0, so f = K delta / (z_h - h0)^2 and the exponent is
n = -2 z_h / (z_h - h0), i.e. h0 = z_h (1 + 2 / n). This prints h0 for the paper's and
our means (`jaxloco sweep snake_contact`'s defaults, typed in below as measured on 8
Dec 2026), and then, for each posture of the contact experiment on the no-skid model
(`contact.head_posture`, rigid base), each head-part joint's lever along each push
(|axis x (contact - joint)| . push [m]) and the static force of a position push that
overshoots by OVERSHOOT_MM (default: `contact.OVERSHOOT`) against the head servos'
stiffness alone (`model.KP`): f = delta / sum_i(lever_i^2 / KP). That is an upper bound
on the servo-limited force (the base, the wheels and the contact give too), and its
trend is the head part's geometry.
"""

from __future__ import annotations

import sys

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=True)

import jax.numpy as jnp  # noqa: E402

from jaxloco.robots.snake import contact, kinematics, model  # noqa: E402
from jaxloco.robots.snake import params as sp  # noqa: E402

# `jaxloco sweep snake_contact` at the defaults, mean of 5 trials (docs/snake.md, 8 Dec 2026)
OURS = {"i": (16.0, 15.4, 15.7), "ii": (24.8, 12.2, 11.2), "iii": (30.9, 10.7, 9.4),
        "iv": (13.4, 15.8, 15.8), "v": (18.5, 9.0, 10.6), "vi": (22.4, 7.7, 8.7)}
CONTACT_POINT = ("front", "mid", "mid")  # where the gripper meets the plate per push (`contact.plate_pose`)


def axis_heights(means: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """h0 = z_h (1 + 2 / n) [m] at the middle height (0.35 m) for f_x, f_y per base."""
    return {base: 0.35 * (1.0 + 2.0 / n[:2]) for base, n in contact.height_exponents(means).items()}


def levers(name: str) -> tuple[np.ndarray, float]:
    """(levers (3 pushes, 6 head-part joints) [m], head height [m]) of a posture."""
    z_h, y_h, base = contact.POSTURES[name]
    phi, base_pose = contact.head_posture(z_h, y_h, base)
    head = contact.kinematic_head(phi, base_pose)
    joints = kinematics.full_joint_angles(jnp.asarray(phi))
    R, p = (np.asarray(a) for a in kinematics.link_frames(jnp.asarray(head), joints))
    back, front = contact.gripper_segment(head)
    points = {"front": front, "mid": 0.5 * (back + front)}
    out = np.zeros((3, sp.N_H))
    for d, push in enumerate(contact.PUSH):
        point = points[CONTACT_POINT[d]]
        for k in range(sp.N_H):  # joint k sits at the front of link k + 2 (index k + 1)
            axis = R[k + 1][:, 1] if sp.JOINT_IS_PITCH[k] else -R[k + 1][:, 2]
            out[d, k] = np.cross(axis, point - p[k + 1]) @ push
    return out, float(head[2])


def main(argv: list[str]) -> None:
    delta = float(argv[0]) / 1e3 if argv else contact.OVERSHOOT
    paper = {k: np.array([m for m, _ in f]) for k, f in contact.PAPER_FORCES.items()}
    ours = {k: np.array(v) for k, v in OURS.items()}
    print("force ~ z_h^n over (i)-(iii) / (iv)-(vi); h0: the axis height that exponent implies [m]")
    for label, means in (("paper", paper), ("ours", ours)):
        ex, h0 = contact.height_exponents(means), axis_heights(means)
        for base in ex:
            print(f"  {label:5s} {base:8s} n f_x {ex[base][0]:+.2f} f_y {ex[base][1]:+.2f} f_z {ex[base][2]:+.2f}"
                  f"   h0 f_x {h0[base][0]:+.3f} f_y {h0[base][1]:+.3f}")
    print(f"\nhead-part joint levers [m] and the static force of a {delta * 1e3:g} mm push against KP = "
          f"{model.KP:g} N m/rad alone (rigid base) [N]; the paper's mean beside")
    names = [sp.JOINT_NAMES[k] for k in range(sp.N_H)]
    print(f"{'posture':8s} {'z_h':>5s}  push  " + " ".join(f"{n:>7s}" for n in names) + "   static  paper")
    for name in contact.POSTURE_NAMES:
        lv, z = levers(name)
        for d, push in enumerate(contact.DIRECTIONS):
            force = delta / np.sum(lv[d] ** 2 / model.KP)
            lead = f"({name})" if d == 0 else ""
            zc = f"{z:5.2f}" if d == 0 else " " * 5
            print(f"{lead:8s} {zc}  f_{push}   " + " ".join(f"{v:+7.3f}" for v in lv[d])
                  + f"   {force:6.1f}  {contact.PAPER_FORCES[name][d][0]:5.1f}")


if __name__ == "__main__":
    main(sys.argv[1:])
