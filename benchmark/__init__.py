"""The method and the harness: viewpoints, classifiers, aggregators, post-processing,
metrics, baselines, runner, tables and figures. Imports ``envs``, never the reverse."""
