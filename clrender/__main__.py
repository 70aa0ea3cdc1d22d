"""`python -m clrender ...`: the same as the `clrender` command."""
from .cli import run

if __name__ == "__main__":
    run()
