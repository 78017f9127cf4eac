"""OCTOPUS, the four-arm four-flipper crawler of Chen et al. (ROBOMECH J. 2018): compound
locomotion combining crawling and walking.

Modules: `params` (Tables 1-3, the dimensions chosen where the figures are missing and
`PARAMETERS`, every user parameter stated once),
`model` (the MJCF `models/octopus.xml`), `kinematics` (arm FK/IK, Eqs. 1-6; terrain
exploration, Cases 1-3 and Eqs. 7-9; COG height and travelled distance, Eqs. 10-18),
`clm_rules` (the CLM's control rules, each a pure function), `clm` (the CLM controller),
`ccm` (the crawler-only baseline), `operator` (the operator layer, apart from the CLM),
`scenarios` (steps, terraces, block and pit in MuJoCo), `analysis`
(`octopus.terrain_classification`), `sim_analysis` (`octopus.step_climb`),
`paper_analysis` (`octopus.paper`: the paper's experiments), `tuning` (the
`octopus.sigma` objective), `mjx_tuning` (the `octopus.climb_lift` objective: Delta_E
through an MJX rollout of the CLIMB), `plots`, `entries` (its registry entries).
"""
