"""Writing rosbag2 bags (rosbags library): no ROS import, used by the ``recorder`` node."""
