"""Runs on a Dask cluster: ``--workers N`` (a ``distributed.LocalCluster`` on this machine) or
``--scheduler ADDRESS`` (a cluster started with ``dask scheduler`` / ``dask worker``).

The client makes the scene, lights and trees as a local run does and ships them to every worker once
(:mod:`~lightcuts.distributed.runner`); the tasks are image tiles (crop windows of the image, whose
pixels the kernel computes exactly as in the whole image, :mod:`~lightcuts.distributed.tiles`), the
passes of a converging render, compare rows and scaling points (:mod:`~lightcuts.distributed.studies`),
so the outputs are those of the local run, byte for byte. On a worker (:mod:`~lightcuts.distributed.worker`)
one lightcuts task runs at a time, on the worker's share of the cores, with the ray caster built
once per run. :mod:`~lightcuts.distributed.options` (the command-line flags) imports no Dask:
without ``--workers`` / ``--scheduler``, ``distributed`` is never imported.
"""
