"""The leg-grope walk (Ambe & Matsuno, ROBOMECH J. 2016): a small quadruped that probes
each foothold with a reference force before trusting it, walking on fragile slopes.

Modules: `params` (Table 1 robot), `kinematics` (leg FK, IK, Jacobians), `regions`
(admissible COG and groping-leg regions, Eqs. 2-10), `gait` (one leg-grope walk cycle
on a slope), `forces` (the force-distribution QP, Eqs. 15-22, over the cycle) and
`analysis` (the `leggrope.slope_cycle` sweep analysis).
"""
