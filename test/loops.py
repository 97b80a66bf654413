"""The robots, gains and set-points the closed-loop tests share (node processes in
test/integration, the in-process engine in test/unit)."""

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
#: Inverse dynamics: start configurations and steps whose peak torque B(q0)K_PΔ + g(q0)
#: stays well inside the effort limits (the second-order theory holds only without
#: saturation).
ID_CASES = {
    "planar_2dof": {
        "q0": [-1.0, 0.5],
        "omega_n": [8.0, 12.0],
        "zeta": [0.5, 0.8],
        "step": [0.1, -0.15],
        "duration": 2.5,
    },
    "iiwa": {
        "q0": [0.0, 0.3, 0.0, -1.2, 0.0, 0.6, 0.0],
        "omega_n": [8.0, 8.0, 10.0, 10.0, 12.0, 12.0, 12.0],
        "zeta": [0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.8],
        "step": [0.1, -0.1, 0.1, 0.1, -0.1, 0.1, 0.1],
        "duration": 2.5,
    },
}
