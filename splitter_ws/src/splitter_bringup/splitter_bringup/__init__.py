"""SPLITTER scenarios, launcher, runs, benchmarks and CLI."""
