"""``python -m critfric``: the command line."""

from critfric.cli import main

if __name__ == "__main__":
    main()
