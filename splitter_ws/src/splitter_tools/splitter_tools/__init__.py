"""SPLITTER tools beside the runtime: the benchmarks (``splitter bench``), the transport
floor of the graph and the garbage harness of the graph tests."""
