"""``splitter bag {info,recover,play,record}``: the bag tools of ``ros2 bag`` this project needs.

``info`` prints what ``ros2 bag info`` prints and checks metadata.yaml against
the MCAP statistics; ``recover`` completes a bag whose recorder was killed;
``play`` and ``record`` run the player and recorder nodes in this process.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from splitter_bag.core.info import bag_size_bytes, check_consistency, format_bag_info
from splitter_bag.core.metadata import MetadataError, read_metadata
from splitter_bag.core.recover import RecoveryError, recover_bag

_log = logging.getLogger(__name__)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")

    info = sub.add_parser("info", help="topics, types, counts and duration of a bag")
    info.add_argument("bag", type=Path, help="bag directory")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")

    recover = sub.add_parser("recover", help="complete a bag whose recorder was killed")
    recover.add_argument("bag", type=Path, help="bag directory")

    play = sub.add_parser("play", help="replay a bag with its original timing")
    play.add_argument("bag", type=Path, help="bag directory")
    play.add_argument("-r", "--rate", type=float, default=1.0, help="rate factor")
    play.add_argument("-l", "--loop", action="store_true", help="play in a loop")
    play.add_argument("--start-offset", type=float, default=0.0, help="skip this much [s]")
    play.add_argument("--topics", nargs="*", default=[], help="topics to play (default all)")
    play.add_argument("--regex", default="", help="also play topics matching this regex")
    play.add_argument("--exclude-regex", default="", help="never play these topics")
    play.add_argument("--clock", type=float, default=100.0, help="/clock rate [Hz] (0: no /clock)")
    play.add_argument("--delay", type=float, default=0.5, help="wait before playing [s]")

    record = sub.add_parser("record", help="record topics of the running graph")
    record.add_argument("-o", "--output", default="", help="bag directory to create")
    record.add_argument("topics", nargs="*", help="topics to record (default all)")
    record.add_argument("-e", "--regex", default="", help="also record topics matching this")
    record.add_argument("-x", "--exclude-regex", default="", help="never record these topics")
    record.add_argument(
        "-b", "--max-bag-size", type=int, default=0, help="split at this file size [B]"
    )
    record.add_argument(
        "-d", "--max-bag-duration", type=float, default=0.0, help="split every this many [s]"
    )
    record.add_argument(
        "--compression", choices=("zstd", "none"), default="zstd", help="chunk compression"
    )
    record.add_argument(
        "--use-sim-time", action="store_true", help="log time from /clock (simulated time)"
    )
    record.add_argument(
        "--publish-time",
        choices=("header", "source_timestamp"),
        default="header",
        help="MCAP publish time: header.stamp, or the middleware's source timestamp",
    )


def _info(args: argparse.Namespace) -> int:
    metadata = read_metadata(args.bag)
    report = check_consistency(args.bag)
    if args.json:
        print(
            json.dumps(
                {
                    "bag": str(args.bag),
                    "files": list(metadata.relative_file_paths),
                    "bag_size_bytes": bag_size_bytes(args.bag),
                    "storage_identifier": metadata.storage_identifier,
                    "ros_distro": metadata.ros_distro,
                    "duration_s": metadata.duration_ns / 1e9,
                    "starting_time_ns": metadata.starting_time_ns,
                    "message_count": metadata.message_count,
                    "topics": [
                        {
                            "name": t.topic_metadata.name,
                            "type": t.topic_metadata.type,
                            "count": t.message_count,
                            "serialization_format": t.topic_metadata.serialization_format,
                        }
                        for t in metadata.topics_with_message_count
                    ],
                    "consistent": report.ok,
                    "problems": list(report.problems),
                },
                indent=2,
            )
        )
    else:
        print(format_bag_info(metadata, bag_size_bytes(args.bag)))
        for problem in report.problems:
            print(f"INCONSISTENT: {problem}", file=sys.stderr)
    return 0 if report.ok else 1


def _recover(args: argparse.Namespace) -> int:
    report = recover_bag(args.bag)
    print(report.summary())
    return 0


def _play(args: argparse.Namespace) -> int:
    from rclpy.parameter import Parameter

    from splitter_bag import player_node

    overrides = [
        Parameter("bag", value=str(args.bag)),
        Parameter("rate", value=float(args.rate)),
        Parameter("loop", value=bool(args.loop)),
        Parameter("start_offset_s", value=float(args.start_offset)),
        Parameter("topics", value=",".join(args.topics)),
        Parameter("regex", value=args.regex),
        Parameter("exclude_regex", value=args.exclude_regex),
        Parameter("clock_rate_hz", value=float(args.clock)),
        Parameter("start_delay_s", value=float(args.delay)),
    ]
    return player_node.run(overrides)


def _record(args: argparse.Namespace) -> int:
    from rclpy.parameter import Parameter

    from splitter_bag import recorder_node

    overrides = [
        Parameter("output", value=args.output),
        Parameter("topics", value=",".join(args.topics)),
        Parameter("regex", value=args.regex),
        Parameter("exclude_regex", value=args.exclude_regex),
        Parameter("max_bagfile_size_bytes", value=int(args.max_bag_size)),
        Parameter("max_bagfile_duration_s", value=float(args.max_bag_duration)),
        Parameter("compression", value=args.compression),
        Parameter("publish_time", value=args.publish_time),
        Parameter("use_sim_time", value=bool(args.use_sim_time)),
    ]
    return recorder_node.run(overrides)


def main(args: argparse.Namespace) -> int:
    actions = {"info": _info, "recover": _recover, "play": _play, "record": _record}
    try:
        return actions[args.action](args)
    except (MetadataError, RecoveryError, FileNotFoundError) as exc:
        print(f"splitter bag {args.action}: {exc}", file=sys.stderr)
        return 1
