"""An example metric plug-in for roomseg-bench (docs/plugins.md)."""
