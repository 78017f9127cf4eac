"""The leg-grope walk (Ambe & Matsuno, ROBOMECH J. 2016): a small quadruped that probes
each foothold with a reference force before trusting it, walking on fragile slopes.

Modules: `params` (Table 1 robot), `kinematics` (leg FK, IK, Jacobians), `regions`
(admissible COG and groping-leg regions, Eqs. 2-10), `design` (the footstep sequence of
a cycle), `gait` (one leg-grope walk cycle on a slope), `forces` (the force-distribution
QP, Eqs. 15-22, over the cycle), `analysis` (the `leggrope.slope_cycle` sweep analysis),
`results` (reading its table: status categories, critical theta), `model` (the MJCF
`models/leggrope.xml`), `control` (the experimental walk, steps A'-D', as a controller),
`scenarios` (the walk over fragile footholds in MuJoCo, and its MJX variant),
`sim_analysis` (`leggrope.fragile_walk`), `mjx_tuning` (`leggrope.shear_relief`, the
shear-relief gain tuned through MJX), `plots`, `entries` (its registry entries).
"""
