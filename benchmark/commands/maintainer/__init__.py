"""The maintainers' tools, apart from the user's commands (``roomseg --help`` does not list them;
``make help`` runs them): the docs site's generated pages and block runner, the README's
generated blocks, the speed and scaling benchmarks, the GPU check, the VLM's cost, the bag-memory
measurement and the SLAM levels' table. Each runs as ``python -m
benchmark.commands.maintainer.<name>``."""
