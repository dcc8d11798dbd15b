"""Run a node's ``main()`` given as ``module:function`` (the launcher's way to start nodes).

``python -m splitter_bringup.run.node_runner splitter_sim.simulator_node:main --ros-args ...``
The remaining arguments become ``sys.argv`` so that ``rclpy.init`` sees them.
It works the same in a virtual environment and in a colcon install, where
console scripts live in different places.

Started by the launcher (``SPLITTER_PARENT_PID`` set), the node first asks the kernel
to kill it when the launcher ends, however it ends
(:func:`splitter_msgs_py.lifetime.die_with_parent`).
"""

from __future__ import annotations

import importlib
import sys

from splitter_msgs_py.lifetime import die_with_parent_from_env


def main() -> int:
    """Import the entry and call it with the rest of the command line as argv."""
    if len(sys.argv) < 2 or ":" not in sys.argv[1]:
        print(
            "usage: python -m splitter_bringup.run.node_runner module:function [args]",
            file=sys.stderr,
        )
        return 2
    die_with_parent_from_env()
    module_name, function_name = sys.argv[1].split(":", 1)
    entry = getattr(importlib.import_module(module_name), function_name)
    sys.argv = [module_name, *sys.argv[2:]]
    result = entry()
    return int(result or 0)


if __name__ == "__main__":
    sys.exit(main())
