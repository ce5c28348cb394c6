"""Launch flow_node with an input remapping and a parameter file.

    ros2 launch flow_node flow_node.launch.py image:=/camera/image_raw params_file:=/path/to/realtime.yaml

Arguments: ``image`` (input topic, default /image), ``params_file`` (default the package's
config/flow_node.yaml), ``namespace`` (default empty), ``node_name`` (default flow_node), ``log_level``,
``dds_profile`` (a Fast DDS XML profile for the node's process; empty, the default, leaves the choice to the
node, whose ``main()`` applies the package's config/fastdds_localhost.xml unless the environment already names a
profile, Fast DDS's built-in transports or another RMW: ``startup.use_shipped_dds_profile``, docs/node.md,
"Middleware").
"""

from launch.actions import DeclareLaunchArgument, SetEnvironmentVariable
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, NotEqualsSubstitution, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from launch import LaunchDescription


def generate_launch_description() -> LaunchDescription:
    default_params = PathJoinSubstitution([FindPackageShare("flow_node"), "config", "flow_node.yaml"])
    return LaunchDescription([
        DeclareLaunchArgument("image", default_value="/image", description="input sensor_msgs/Image topic"),
        DeclareLaunchArgument("params_file", default_value=default_params,
                              description="ROS parameter file (see config/*.yaml)"),
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the node"),
        DeclareLaunchArgument("node_name", default_value="flow_node", description="name of the node"),
        DeclareLaunchArgument("log_level", default_value="info", description="logging level"),
        DeclareLaunchArgument("dds_profile", default_value="",
                              description="Fast DDS XML profile for the node's process (empty: the node's own rule)"),
        SetEnvironmentVariable("FASTRTPS_DEFAULT_PROFILES_FILE", LaunchConfiguration("dds_profile"),
                               condition=IfCondition(NotEqualsSubstitution(LaunchConfiguration("dds_profile"), ""))),
        Node(
            package="flow_node",
            executable="flow_node",
            name=LaunchConfiguration("node_name"),
            namespace=LaunchConfiguration("namespace"),
            parameters=[LaunchConfiguration("params_file")],
            remappings=[("image", LaunchConfiguration("image")),
                        ("image/compressed", [LaunchConfiguration("image"), "/compressed"])],
            arguments=["--ros-args", "--log-level", LaunchConfiguration("log_level")],
            output="screen",
            emulate_tty=True,
        ),
    ])
