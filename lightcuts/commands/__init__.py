"""The command-line commands, one module each, above every stage.

Each module has ``add_parser(subparsers)`` and ``run(args) -> int``. A command loads its config
(:mod:`lightcuts.config`), resolves and checks every name in its plan step (:mod:`.plan`), checks
its output folder, and then drives the stages in the order they run: ``scene`` -> ``accel`` (the
ray caster over the scene's triangles) -> ``lights`` (the particle tracer casts rays with it) ->
``trees`` -> ``render`` -> ``report`` (-> ``mitsuba``, the optional reference renderer). ``render``
and ``compare`` run through the Python API (:mod:`lightcuts.api`) and only parse options, save and
print. Beside the commands: :mod:`.scaling_gather` (``scaling --gather``), :mod:`.plan` (the plan
step), :mod:`.common` (``--set``, progress bars, the timed render) and :mod:`.warmup` (numba's
compile notice, the render kernel compiled in a second process). Stages never import a command.
"""

#: The command modules, in the order ``lightcuts --help`` lists them.
COMMANDS = ("lights", "tree", "scaling", "render", "compare", "study", "accel", "reference", "convert", "plugins")
