"""The command-line commands, one module each, above every stage.

Each module has ``add_parser(subparsers)`` and ``run(args) -> int``. A command loads its config
(:mod:`lightcuts.config`), resolves and checks every name in its plan step (:mod:`.plan`), and then
drives the stages in their order: ``scene`` -> ``lights`` -> ``trees`` -> ``accel`` (ray casting)
-> ``render`` -> ``report`` (-> ``mitsuba``, the optional reference renderer). Stages never import a
command.
"""

#: The command modules, in the order ``lightcuts --help`` lists them.
COMMANDS = ("lights", "tree", "scaling", "render", "compare", "accel", "reference")
