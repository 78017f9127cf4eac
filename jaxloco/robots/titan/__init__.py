"""TITAN XI, the 7 t quadruped for steep-slope work of Hodoshima et al. (J. Robot.
Mechatron. 19(1), 2007): the grid step over intermittent crawl gait.

Modules: `params` (Table 1 and the dimensions chosen where the figures are missing),
`kinematics` (leg geometry), `maps` (unevenness and forbidden-foothold grid maps, Section
8.2.1, and the Section 7 / 8.4 frame scenarios), `gait` (planar and height gait of
Sections 5-6, `plan_cycles`), `analysis` (`titan.stride`), `tuning` (the `titan.stride`
objective), `mjx_tuning` (the `titan.body_gain` objective, through MJX), `model` (the
MJCF `models/titan_xi.xml`), `control` (the quasi-static footstep executor), `scenarios`
and `walk` (the plan executed in MuJoCo, on native MuJoCo or MJX), `localization`
(self-localisation by surveying, Sec. 8.2.2), `sim_analysis` (`titan.walk`), `plots`,
`entries` (its registry entries).
"""
