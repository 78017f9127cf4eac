"""OCTOPUS, the four-arm four-flipper crawler of Chen et al. (ROBOMECH J. 2018): compound
locomotion combining crawling and walking.

Modules: `params` (Tables 1-3 and the dimensions chosen where the figures are missing),
`model` (the MJCF `models/octopus.xml`), `kinematics` (arm FK/IK, Eqs. 1-6; terrain
exploration, Cases 1-3 and Eqs. 7-9; COG height and travelled distance, Eqs. 10-18).
"""
