"""The run pipeline: the plan (every name a run uses resolved before any work), the stages driven in
order (scene -> ray caster -> lights -> trees -> integrator -> result), the timed image, the passes,
the kernel warm-up, and the runs of ``render``, ``compare`` and the convergence studies that the
Python API (:mod:`lightcuts.api`), the commands and :mod:`lightcuts.distributed` build on. It
imports the stages only; nothing here imports the API, the commands or the cluster code."""
