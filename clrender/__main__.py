"""`python -m clrender ...`: the same as the `clrender` command."""
from clrender.cli.app import run

if __name__ == "__main__":
    run()
