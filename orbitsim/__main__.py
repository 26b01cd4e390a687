"""``python -m orbitsim`` behaves exactly like the ``orbitsim`` command."""

from orbitsim.cli.main import main

if __name__ == "__main__":
    main()
