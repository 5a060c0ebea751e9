"""An example aggregator plug-in for roomseg-bench (docs/plugins.md)."""
