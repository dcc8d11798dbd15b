"""Subcommands of the ``splitter`` command that belong to the bringup package."""
