"""roomseg-bench's Hydra plugins: the ``grids`` sweeper and the ``local`` launcher
(``conf/hydra/sweeper/grids.yaml``, ``conf/hydra/launcher/local.yaml``).

They live under the ``hydra_plugins`` namespace because that is where Hydra looks for
plugins, and import nothing of the project but one standard-library-only module
(:mod:`benchmark.harness.processes`): Hydra imports them whenever an app starts.
"""
