"""Batched closed-loop simulation: one rollout API over MuJoCo native (mujoco.batch) and MJX."""
