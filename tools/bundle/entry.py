"""The standalone bundle's program: ``bpms`` as the wheel installs it (tools/bundle/bpms.spec).

``freeze_support`` lets ``bpms batch``'s worker processes start from the frozen program under
the "spawn" start method (Windows, macOS)."""

import multiprocessing
import sys

if __name__ == "__main__":
    multiprocessing.freeze_support()
    from bpms.cli import main

    sys.exit(main())
