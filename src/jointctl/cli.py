"""Command-line interface (placeholder until the commands are wired)."""


def main(argv=None) -> int:
    return 0
