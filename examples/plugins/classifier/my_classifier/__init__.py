"""An example classifier plug-in for roomseg-bench (docs/plugins.md)."""
