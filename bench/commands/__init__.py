"""CLI command groups; each module registers its sub-commands with ``register(subparsers)``."""
