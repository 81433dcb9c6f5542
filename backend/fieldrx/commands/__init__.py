"""Command-line subcommands of `fieldrx` (each module: register(subparsers) and run(args))."""
