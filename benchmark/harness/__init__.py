"""The harness: the run store (where runs, jobs, rows, maps and cache entries live), the
content-addressed caches, the per-house pipeline and the runner that builds it from a
config. Algorithms know nothing of it."""
