"""``python -m balancer_id``: the ``balancer-id`` command.

``python -m`` puts the working folder first on ``sys.path``; a program never imports from
there (a ``multiprocessing.py`` or ``json.py`` lying in a folder of logs would run as the
user), so it is taken off before anything else is imported, as the ``balancer-id`` script
never has it.
"""

import os
import sys

if sys.path and sys.path[0] in ("", os.getcwd()) and not sys.flags.safe_path:
    del sys.path[0]

from balancer_id.cli import main

if __name__ == "__main__":
    main()
