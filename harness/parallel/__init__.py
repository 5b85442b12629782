"""Parallel runs: a suite's independent tasks on local processes or a Dask cluster (cluster.py), and one
worker against N on the same job (cluster_bench.py, ``python -m harness.parallel.cluster_bench``)."""
