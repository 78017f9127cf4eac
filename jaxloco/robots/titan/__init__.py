"""TITAN XI, the 7 t quadruped for steep-slope work of Hodoshima et al. (J. Robot.
Mechatron. 19(1), 2007): the grid step over intermittent crawl gait.

Modules: `params` (Table 1 and the dimensions chosen where the figures are missing),
`maps` (unevenness and forbidden-foothold grid maps, Section 8.2.1, and the Section 7 /
8.4 frame scenarios), `gait` (planar and height gait of Sections 5-6, `plan_cycles`).
"""
