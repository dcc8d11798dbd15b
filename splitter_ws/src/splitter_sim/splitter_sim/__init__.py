"""SPLITTER variable-inertia rigid-body simulator and its node."""
