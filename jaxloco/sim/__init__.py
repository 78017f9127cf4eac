"""Batched closed-loop simulation: one rollout API over MuJoCo native (mujoco.batch) and MJX.

Modules: `rollout` (the one API: scenario, parameter batch, backend -> records and
metrics), `scenario` (what a rollout needs: model, terrain, initial state, controller),
`data` (the simulator data a controller reads, the same from every backend), `native`
(the mujoco.batch backend), `mjx` (the MJX backend), `programs` (traced MJX programs
kept on disk for later processes), `backend` (which of the two runs: native, mjx or
auto), `terrain` (terrains whose parameters change per simulation), `mjcf` (loading and
writing the robots' MJCF files), `metrics` (metrics of recorded rollouts).
"""
