"""The ROS-free parts of the bag: MCAP writer and reader, metadata.yaml, recovery, playback."""
