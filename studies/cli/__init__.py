"""The command line: ``hingelab`` (``main``) and one module per subcommand.

Each subcommand module has ``register(sub)`` (its options) and ``run(args)``; ``main``
lists them. ``args`` and ``options`` hold the options several subcommands share.
"""
