"""The robots, gains and set-points the closed-loop tests share (node processes in
tests/integration, the in-process engine in tests/unit)."""

#: Gains that are well damped and stable at 1 kHz for each robot (K_D T_s ≪ B_ii).
GAINS = {
    "planar_2dof": {"kp": [2000.0, 1000.0], "kd": [900.0, 300.0]},
    "iiwa": {
        "kp": [300.0, 300.0, 200.0, 200.0, 50.0, 50.0, 10.0],
        "kd": [20.0, 40.0, 10.0, 10.0, 1.0, 1.0, 0.2],
    },
}
SETPOINTS = {
    "planar_2dof": [0.5, -0.3],
    "iiwa": [0.3, 0.5, -0.2, -1.0, 0.2, 0.8, 0.1],
}
JOINTS = {
    "planar_2dof": ["joint1", "joint2"],
    "iiwa": [f"lbr_iiwa_joint_{i}" for i in range(1, 8)],
}
