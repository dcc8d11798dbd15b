"""The ``splitter`` command (:mod:`.main`) and its verbs: each parses its arguments and calls
the library."""
