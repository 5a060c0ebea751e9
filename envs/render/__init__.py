"""Rendering: what a camera at a pose sees. The contract (:class:`envs.render.base.Renderer`,
:class:`envs.render.observation.Observation`), ray casting, the offline floorplan renderer,
the AI2-THOR and Habitat-Sim adapters (simulators imported lazily) and the render cache."""
