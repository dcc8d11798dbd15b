"""SPLITTER interface layer: names, QoS, conversions, MCAP bags."""
