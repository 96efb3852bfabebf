"""conica-ros: a ROS 1 node between CRTK-style topics and conica-server (see clients/ros/README.md).

frames: the rigid transform between a ROS frame (REP-103: right-handed, metres, z up) and the
server's scene frame; link: the server connection (the conica package when installed, else pyzmq
and the generated protocol module); node: the rospy node."""
