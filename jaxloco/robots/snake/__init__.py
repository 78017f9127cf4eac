"""T² Snake-3 with the Omni-gripper, the wheeled articulated mobile robot of Tanaka et
al., "Task-Space Control of Articulated Mobile Robots With a Soft Gripper for
Operations", IEEE T-RO 35(1), 2019.

Modules: `params` (Table I, the dimensions chosen where the paper is silent and
`PARAMETERS`, every user parameter stated once),
`kinematics` (forward kinematics of the chain, the wheel contact points, the centre of
mass, the velocity constraints of Eqs. 2-8 per mode of Table II and the augmented model
of Eqs. 9-11), `control` (the control law of Eqs. 12-20 and the mode switching of Sec.
IV-C5), `kinsim` (the pure-JAX kinematic closed loop), `experiments` (Sec. V-A and V-B
as data and metrics), `analysis` (sweep analysis `snake.kv`), `tuning` (tune objective
`snake.kv`), `model` (the MJCF `models/t2snake3.xml`), `scenarios` (the MuJoCo
scenario and wheel lifting), `sim_control` (the controller and the experiments in
MuJoCo), `table3` and `contact` (Tables III-V in MuJoCo, analyses `snake.table3`,
`snake.contact`), `operator` (the teleoperator model), `operations` (the pipe, the valve
and the door of Sec. V-D), `operations_analysis` (analysis `snake.operations`),
`predictive` (predictive mode selection), `trials` (the perturbed trials' parameters),
`sim_analysis` and `mjx_tuning` (`snake.reach` and its MJX gain objective), `plots`,
`entries` (its registry entries).
"""
