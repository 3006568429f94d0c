"""Command line of brdfpipe (placeholder entry; subcommands are added below)."""
