"""rosbag2-compatible MCAP bags: writer, reader, recovery, playback schedule.

The modules here are ROS-free except :mod:`splitter_bag.ros_qos`, the
bridge between rclpy QoS profiles and the bag's. Typical use::

    from splitter_bag import BagWriter, read_messages, recover_bag

    with BagWriter("runs/x/bag") as bag:
        bag.add_topic("/splitter/imu", "sensor_msgs/msg/Imu")
        bag.write("/splitter/imu", cdr_bytes, log_time_ns, publish_time_ns)

    for topic, type_name, log_ns, pub_ns, cdr in read_messages("runs/x/bag"):
        ...
"""

from splitter_bag.core.metadata import (
    BagMetadata,
    MetadataError,
    QosProfile,
    TopicMetadata,
    read_metadata,
)
from splitter_bag.core.reader import BagMessage, read_mcap_statistics, read_messages
from splitter_bag.core.recover import RecoveryReport, recover_bag
from splitter_bag.core.writer import BagWriter, BagWriterError, WriterOptions

__all__ = [
    "BagMessage",
    "BagMetadata",
    "BagWriter",
    "BagWriterError",
    "MetadataError",
    "QosProfile",
    "RecoveryReport",
    "TopicMetadata",
    "WriterOptions",
    "read_mcap_statistics",
    "read_messages",
    "read_metadata",
    "recover_bag",
]
