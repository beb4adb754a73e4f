"""One short module per command. Each defines ``register(subparsers)``, which adds its parser and sets
``func`` (a callable taking the parsed args and returning an exit code)."""

COMMANDS = ("train", "run", "fit", "bench", "transfer", "refine")
