"""``python -m critfric``: the command line."""

if __name__ == "__main__":
    try:  # a Ctrl-C this early (a loaded machine) is still one line and exit code 130
        from .cli import main
    except KeyboardInterrupt:
        from .cli import _interrupted

        _interrupted("critfric: interrupted")
    main()
