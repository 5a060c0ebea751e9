"""Datasets: the environment contract (:class:`envs.datasets.base.Environment`) and the sets
of houses the runner sweeps: ProcTHOR (house files or ``prior``), ArchitecTHOR, and the
seeded generator of synthetic houses."""
