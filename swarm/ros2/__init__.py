"""The swarm seen and driven from ROS 2: message types, CDR and type hashes
(messages), rmw_zenoh's keys, attachments and liveliness tokens (rmw), and the
swarm's topics built from one tick (topics). Needs the ``ros2`` extra
(rosbags); only ``rmw`` loads Zenoh."""
