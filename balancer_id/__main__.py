"""``python -m balancer_id``: the ``balancer-id`` command."""

from balancer_id.cli import main

if __name__ == "__main__":
    main()
