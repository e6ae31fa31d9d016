"""CLI commands. Every module here that defines a module-level ``COMMAND`` (a click command) is added to ``linnet``;
modules named ``bench_*`` are added as subcommands of ``linnet bench`` instead."""
