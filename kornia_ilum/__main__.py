"""``python -m kornia_ilum``: the ``kornia-ilum`` command line (see :mod:`kornia_ilum.cli`)."""

from kornia_ilum.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
