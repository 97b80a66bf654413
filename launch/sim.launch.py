"""The simulated loop: sim_bridge (the plant), a controller, a reference, and on request the
recorder and the dashboard, with the package's parameter files (README, "From ROS").

    ros2 launch joint_space_control sim.launch.py
    ros2 launch joint_space_control sim.launch.py controller:=inverse_dynamics mode:=lockstep
    ros2 launch joint_space_control sim.launch.py record:=true output:=/tmp/run1 view:=true
    ros2 launch joint_space_control sim.launch.py robot:=iiwa \
        controller_params:=<share>/config/pd_gravity_controller_iiwa.yaml reference:=false
    ros2 launch joint_space_control sim.launch.py --show-args     # every argument

Each node reads its file under share/joint_space_control/config/ (sim_bridge.yaml,
<controller>_controller.yaml, trajectory_generator.yaml), then what the arguments set: the
robot (`robot`, or `urdf_path` that wins over it, as on the nodes), the plant's `engine`,
`mode` and `initial_positions` (every joint at 0 by default, whatever the robot's size).
Another robot than planar_2dof needs its own gains (`controller_params`) and set-point
(`reference_params`, or `reference:=false`). Everything but the plant runs on its /clock
(use_sim_time). One controller per plant: sim_bridge takes commands from one commander at a
time.
"""

# ruff: noqa: I001  (ruff takes `launch` for this folder, a first-party module: it is ROS's)
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import (
    EqualsSubstitution,
    IfElseSubstitution,
    LaunchConfiguration,
    PathJoinSubstitution,
)
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

PACKAGE = "joint_space_control"


def generate_launch_description() -> LaunchDescription:
    config = PathJoinSubstitution([FindPackageShare(PACKAGE), "config"])
    robot = LaunchConfiguration("robot")
    urdf_path = LaunchConfiguration("urdf_path")
    controller = LaunchConfiguration("controller")
    # The nodes refuse 'robot' and 'urdf_path' together: the parameter files name a robot,
    # so a given urdf_path clears it (urdf_path wins, as on the nodes).
    robot_parameters = {
        "robot": ParameterValue(
            IfElseSubstitution(EqualsSubstitution(urdf_path, ""), robot, ""), value_type=str
        ),
        "urdf_path": ParameterValue(urdf_path, value_type=str),
    }
    on_sim_time = {"use_sim_time": True}

    arguments = [
        DeclareLaunchArgument(
            "robot",
            default_value="planar_2dof",
            description="Built-in robot: planar_2dof | iiwa | panda",
        ),
        DeclareLaunchArgument(
            "urdf_path", default_value="", description="A .urdf or .xacro file (wins over robot)"
        ),
        DeclareLaunchArgument(
            "engine",
            default_value="pybullet",
            choices=["pybullet", "mujoco"],
            description="Physics engine of the plant",
        ),
        DeclareLaunchArgument(
            "mode",
            default_value="realtime",
            choices=["realtime", "lockstep"],
            description="Plant timing: realtime (wall clock) or lockstep (one step per command)",
        ),
        DeclareLaunchArgument(
            "initial_positions",
            default_value="0.0",
            description="The plant's initial joint positions [rad]: one value for every joint or "
            "one per joint ('[0.5, -0.3]'); wins over sim_params",
        ),
        DeclareLaunchArgument(
            "controller",
            default_value="pd_gravity",
            choices=["pd_gravity", "inverse_dynamics", "none"],
            description="The controller node (<controller>_controller); none: the plant alone",
        ),
        DeclareLaunchArgument(
            "reference",
            default_value="true",
            choices=["true", "false"],
            description="Start trajectory_generator (a step, trajectory_generator.yaml)",
        ),
        DeclareLaunchArgument(
            "record",
            default_value="false",
            choices=["true", "false"],
            description="Record the loop's topics with the recorder (rosbag2, MCAP)",
        ),
        DeclareLaunchArgument(
            "output",
            default_value="",
            description="record: bag directory to create (must not exist); "
            "empty: rosbag2_<date>-<time> in the working directory",
        ),
        DeclareLaunchArgument(
            "view",
            default_value="false",
            choices=["true", "false"],
            description="Start the dashboard (the web page of the loop)",
        ),
        DeclareLaunchArgument("port", default_value="8080", description="view: the page's port"),
        DeclareLaunchArgument(
            "sim_params",
            default_value=PathJoinSubstitution([config, "sim_bridge.yaml"]),
            description="sim_bridge's parameter file",
        ),
        DeclareLaunchArgument(
            "controller_params",
            default_value=[PathJoinSubstitution([config, controller]), "_controller.yaml"],
            description="The controller's parameter file",
        ),
        DeclareLaunchArgument(
            "reference_params",
            default_value=PathJoinSubstitution([config, "trajectory_generator.yaml"]),
            description="trajectory_generator's parameter file",
        ),
    ]

    nodes = [
        Node(
            package=PACKAGE,
            executable="sim_bridge",
            output="screen",
            parameters=[
                LaunchConfiguration("sim_params"),
                robot_parameters,
                {
                    "engine": LaunchConfiguration("engine"),
                    "mode": LaunchConfiguration("mode"),
                    "initial_positions": LaunchConfiguration("initial_positions"),
                },
            ],
        ),
        Node(
            package=PACKAGE,
            executable=[controller, "_controller"],
            output="screen",
            parameters=[LaunchConfiguration("controller_params"), robot_parameters, on_sim_time],
            condition=UnlessCondition(EqualsSubstitution(controller, "none")),
        ),
        Node(
            package=PACKAGE,
            executable="trajectory_generator",
            output="screen",
            parameters=[LaunchConfiguration("reference_params"), robot_parameters, on_sim_time],
            condition=IfCondition(LaunchConfiguration("reference")),
        ),
        Node(
            package=PACKAGE,
            executable="recorder",
            output="screen",
            parameters=[
                {"output": ParameterValue(LaunchConfiguration("output"), value_type=str)},
                on_sim_time,
            ],
            condition=IfCondition(LaunchConfiguration("record")),
        ),
        Node(
            package=PACKAGE,
            executable="dashboard",
            output="screen",
            parameters=[{"port": ParameterValue(LaunchConfiguration("port"), value_type=int)}],
            condition=IfCondition(LaunchConfiguration("view")),
        ),
    ]
    return LaunchDescription(arguments + nodes)
