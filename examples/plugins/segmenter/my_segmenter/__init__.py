"""An example segmenter plug-in for roomseg-bench (docs/plugins.md)."""
