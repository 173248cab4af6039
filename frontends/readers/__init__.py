"""Log readers: ROS1/ROS2 bags and CARMEN laser logs, behind one Protocol."""
