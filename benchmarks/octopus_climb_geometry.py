"""What the OCTOPUS crawlers' side profile asks of a step climb (closed form,
`jaxloco.robots.octopus.kinematics`; docs/octopus.md, "What the geometry asks"): for each
rear flipper angle, the least nose-up pitch at which the robot, resting on its rear
flipper tips, holds its front main wheel at the top of the step, the rear axle's height
there, and the pitch at which it turns over backwards on those tips; the height of
the rear axle the paper's 0.60 rad would need; how far ahead of the edge the COG gets on
the rear flipper tips and the edge alone, and where the COG would have to be for it to
pass the edge. Optionally writes the figures (`plots.plot_climb_geometry`,
`plots.plot_cog_lead`).

    python benchmarks/octopus_climb_geometry.py [--height H] [--out docs/gallery/octopus_climb_geometry.png]
        [--out-lead docs/gallery/octopus_cog_lead.png]
"""

from __future__ import annotations

import argparse

import numpy as np

from jaxloco import runtime

runtime.configure(x64=True, cache_dir=False)

from jaxloco.robots.octopus import kinematics, params, plots  # noqa: E402

PAPER_PITCH = 0.60  # [rad] the paper's max pitch climbing the 400 mm step (Fig. 12)
MU = 0.8  # the scenarios' nominal friction (default, ours)
# [rad] where our climbs stall with their tracks loaded: the common-axis and rear-flipper
# readings of `python benchmarks/octopus_experiments.py 20` and docs/octopus.md's climb table
STALL = (0.80, 0.93)


def cog_needed_ahead(step_height: float, profile: kinematics.CrawlerProfile = kinematics.CrawlerProfile(),
                     tol: float = 1e-3) -> float:
    """How far ahead of the rear main axle [m] (along the body, at the profile's COG
    height) the COG would have to be for `kinematics.cog_lead_over_edge_on_rear_tips` to
    reach 0, i.e. for the robot to tip forward onto the top on its rear flipper tips and
    the edge alone. Bisection over 0-1 m; inf if even 1 m is not enough."""
    def passes(cog_x: float) -> bool:
        return float(kinematics.cog_lead_over_edge_on_rear_tips(step_height, profile._replace(cog_x=cog_x))[0]) >= 0.0

    lo, hi = 0.0, 1.0
    if not passes(hi):
        return float("inf")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if passes(mid) else (mid, hi)
    return hi


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--height", type=float, default=0.4, help="step height [m] (default 0.4)")
    ap.add_argument("--out", default=None, help="write the figure here (PNG)")
    ap.add_argument("--out-lead", default=None,
                    help="write the COG-over-the-edge figure here (PNG, `plots.plot_cog_lead`)")
    args = ap.parse_args()
    if not 0.0 < args.height < 1.0:
        ap.error(f"--height {args.height:g}: expected a step height in (0, 1) m")
    h = args.height
    rear_needed = float(kinematics.rear_axle_height_to_mount(h, PAPER_PITCH))
    print(f"step {h:g} m: front main axle needed at {h + params.MAIN_WHEEL_RADIUS:.3f} m; at the paper's "
          f"{PAPER_PITCH:g} rad the rear axle must be {rear_needed:.3f} m up; "
          f"atan(mu = {MU:g}) = {np.arctan(MU):.3f} rad")
    print(f"{'rear flipper [rad]':>18} {'[deg]':>6} {'least pitch [rad]':>18} {'rear axle there [m]':>20} "
          f"{'tips over at [rad]':>19}")
    for rear in (0.2, 0.0, -0.2, -0.4, -0.6, -0.83, -1.0, -1.2, -params.FLIPPER_LIMIT):
        p = float(kinematics.mount_pitch_on_rear_tips(h, rear))
        axle = float(kinematics.rear_axle_height_to_mount(h, p)) if np.isfinite(p) else float("nan")
        tip = float(kinematics.tipping_pitch_on_rear_tips(rear))
        print(f"{rear:>18.2f} {np.degrees(rear):>6.0f} {p:>18.3f} {axle:>20.3f} {tip:>19.3f}")
    margin, rear, pitch = (float(v) for v in kinematics.cog_lead_over_edge_on_rear_tips(h))
    print(f"on the rear flipper tips with the main crawler's bottom on the edge, up to turning over backwards: "
          f"the COG at best {margin:+.3f} m ahead of the edge (rear flippers {rear:+.2f} rad, pitch {pitch:.2f} rad)")
    profile = kinematics.CrawlerProfile()
    body = profile.axle_spacing + 2 * profile.wheel_radius
    for label, cog_z in (("at our COG height", profile.cog_z), ("at the rear axle's height", 0.0)):
        need = cog_needed_ahead(h, profile._replace(cog_z=cog_z))
        print(f"for that bound to reach 0 the COG ({label}, {cog_z:.3f} m above the axle) would have to be "
              f"{need:.3f} m ahead of the rear axle (ours {profile.cog_x:.3f}; the main crawler ends "
              f"{profile.axle_spacing + profile.wheel_radius:.3f} m ahead of it, the body is {body:.2f} m long)")
    if args.out or args.out_lead:
        import matplotlib

        matplotlib.use("Agg")
    if args.out:
        fig = plots.plot_climb_geometry(h, mu=MU, paper_pitch=PAPER_PITCH, stall=STALL)
        fig.savefig(args.out, dpi=110)
        print(f"wrote {args.out}")
    if args.out_lead:
        plots.plot_cog_lead(h).savefig(args.out_lead, dpi=110)
        print(f"wrote {args.out_lead}")


if __name__ == "__main__":
    main()
