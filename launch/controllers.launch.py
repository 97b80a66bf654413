"""A controller against a robot that already runs: a ros2_control robot (real or simulated)
whose forward command controller takes efforts (docs/ros2_control.md).

    ros2 launch joint_space_control controllers.launch.py
    ros2 launch joint_space_control controllers.launch.py controller:=inverse_dynamics \
        forward_controller:=effort_controller robot:=topic
    ros2 launch joint_space_control controllers.launch.py --show-args     # every argument

The controller reads /joint_states (as joint_state_broadcaster publishes it) and sends
std_msgs/Float64MultiArray to the forward command controller named `forward_controller`
(`command_interface: forward_command`, `-r commands:=/<forward_controller>/commands`), in
`command_joints` order (set in `controller_params` when the forward controller's joints come
in another order than the controlled ones). The robot comes from the latched robot_description
topic by default (`robot:=topic`, as robot_state_publisher publishes it), or a built-in
`robot`, or `urdf_path`. Gains: the package's <controller>_controller.yaml unless
`controller_params` names another file. For a namespaced robot, include this file under a
PushRosNamespace.
"""

# ruff: noqa: I001  (ruff takes `launch` for this folder, a first-party module: it is ROS's)
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
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
    forward_controller = LaunchConfiguration("forward_controller")

    arguments = [
        DeclareLaunchArgument(
            "controller",
            default_value="pd_gravity",
            choices=["pd_gravity", "inverse_dynamics"],
            description="The controller node (<controller>_controller)",
        ),
        DeclareLaunchArgument(
            "robot",
            default_value="topic",
            description="topic: the latched robot_description topic (robot_state_publisher); "
            "or a built-in robot: planar_2dof | iiwa | panda",
        ),
        DeclareLaunchArgument(
            "urdf_path", default_value="", description="A .urdf or .xacro file (wins over robot)"
        ),
        DeclareLaunchArgument(
            "forward_controller",
            default_value="effort_controller",
            description="Name of the robot's forward command (effort) controller: the commands "
            "go to /<forward_controller>/commands",
        ),
        DeclareLaunchArgument(
            "gravity_compensated_by_hardware",
            default_value="false",
            choices=["true", "false"],
            description="The robot adds g(q) itself: ĝ(q) is left out of the command",
        ),
        DeclareLaunchArgument(
            "use_sim_time",
            default_value="false",
            choices=["true", "false"],
            description="true against a simulated robot that publishes /clock",
        ),
        DeclareLaunchArgument(
            "controller_params",
            default_value=[PathJoinSubstitution([config, controller]), "_controller.yaml"],
            description="The controller's parameter file",
        ),
    ]

    node = Node(
        package=PACKAGE,
        executable=[controller, "_controller"],
        output="screen",
        parameters=[
            LaunchConfiguration("controller_params"),
            {
                # The parameter files name a robot: a given urdf_path clears it.
                "robot": ParameterValue(
                    IfElseSubstitution(EqualsSubstitution(urdf_path, ""), robot, ""),
                    value_type=str,
                ),
                "urdf_path": ParameterValue(urdf_path, value_type=str),
                "command_interface": "forward_command",
                "gravity_compensated_by_hardware": ParameterValue(
                    LaunchConfiguration("gravity_compensated_by_hardware"), value_type=bool
                ),
                "use_sim_time": ParameterValue(
                    LaunchConfiguration("use_sim_time"), value_type=bool
                ),
            },
        ],
        remappings=[("commands", ["/", forward_controller, "/commands"])],
    )
    return LaunchDescription([*arguments, node])
