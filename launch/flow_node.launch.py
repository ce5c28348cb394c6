"""Launch flow_node with an input remapping and a parameter file, as a plain or a managed (lifecycle) node.

    ros2 launch flow_node flow_node.launch.py image:=/camera/image_raw params_file:=/path/to/realtime.yaml
    ros2 launch flow_node flow_node.launch.py managed:=true                  # launch configures and activates it
    ros2 launch flow_node flow_node.launch.py managed:=true autostart:=false # it waits for a lifecycle manager

Arguments: ``image`` (input topic, default /image), ``params_file`` (default the package's
config/flow_node.yaml), ``namespace`` (default empty), ``node_name`` (default flow_node), ``log_level``,
``dds_profile`` (a Fast DDS XML profile for the node's process; empty, the default, leaves the choice to the
node, whose ``main()`` applies the package's config/fastdds_localhost.xml unless the environment already names a
profile, Fast DDS's built-in transports or another RMW: ``middleware.use_shipped_dds_profile``, docs/node.md,
"Middleware"), ``managed`` (default false: the node configures and activates itself; true: the node parameter
``managed`` is set and the node starts unconfigured) and ``autostart`` (default true; with ``managed:=true``
the launch file then brings the node to active itself with lifecycle ChangeState events: configure, and
activate once it is inactive; false leaves it unconfigured for a lifecycle manager or ``ros2 lifecycle set``).
The node is a lifecycle node either way (docs/node.md, "Managed (lifecycle) node").
"""

from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler, SetEnvironmentVariable
from launch.conditions import IfCondition
from launch.events import matches_action
from launch.substitutions import AndSubstitution, LaunchConfiguration, NotEqualsSubstitution, PathJoinSubstitution
from launch_ros.actions import LifecycleNode
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare
from lifecycle_msgs.msg import Transition

from launch import LaunchDescription


def generate_launch_description() -> LaunchDescription:
    default_params = PathJoinSubstitution([FindPackageShare("flow_node"), "config", "flow_node.yaml"])
    managed = LaunchConfiguration("managed")
    node = LifecycleNode(
        package="flow_node",
        executable="flow_node",
        name=LaunchConfiguration("node_name"),
        namespace=LaunchConfiguration("namespace"),
        parameters=[LaunchConfiguration("params_file"), {"managed": ParameterValue(managed, value_type=bool)}],
        remappings=[("image", LaunchConfiguration("image")),
                    ("image/compressed", [LaunchConfiguration("image"), "/compressed"])],
        arguments=["--ros-args", "--log-level", LaunchConfiguration("log_level")],
        output="screen",
        emulate_tty=True,
    )
    autostart = IfCondition(AndSubstitution(managed, LaunchConfiguration("autostart")))
    return LaunchDescription([
        DeclareLaunchArgument("image", default_value="/image", description="input sensor_msgs/Image topic"),
        DeclareLaunchArgument("params_file", default_value=default_params,
                              description="ROS parameter file (see config/*.yaml)"),
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the node"),
        DeclareLaunchArgument("node_name", default_value="flow_node", description="name of the node"),
        DeclareLaunchArgument("log_level", default_value="info", description="logging level"),
        DeclareLaunchArgument("dds_profile", default_value="",
                              description="Fast DDS XML profile for the node's process (empty: the node's own rule)"),
        DeclareLaunchArgument("managed", default_value="false", choices=["true", "false"],
                              description="true: a managed lifecycle node, started unconfigured (see autostart); "
                                          "false: the node configures and activates itself"),
        DeclareLaunchArgument("autostart", default_value="true", choices=["true", "false"],
                              description="with managed:=true, configure and activate the node from this launch "
                                          "file (false: leave it to a lifecycle manager)"),
        SetEnvironmentVariable("FASTRTPS_DEFAULT_PROFILES_FILE", LaunchConfiguration("dds_profile"),
                               condition=IfCondition(NotEqualsSubstitution(LaunchConfiguration("dds_profile"), ""))),
        node,
        # once configured (the first time only: a later configure by hand is not followed by an activate)
        RegisterEventHandler(OnStateTransition(
            target_lifecycle_node=node, start_state="configuring", goal_state="inactive", handle_once=True,
            entities=[EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node),
                                                  transition_id=Transition.TRANSITION_ACTIVATE))]),
            condition=autostart),
        EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node),
                                    transition_id=Transition.TRANSITION_CONFIGURE), condition=autostart),
    ])
