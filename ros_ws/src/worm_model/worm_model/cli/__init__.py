"""What every command-line tool of the project shares.

``errors``    bad input said once: InputError (where, what), exit codes, ``run_tool`` (exit 2 on bad
              input, no traceback)
``node_options``  a node's parameters as data (Option rows), declared by the node and read offline
``options``   argparse types (finite, in range, with the unit) and the one-line-error ``Parser``
``progress``  progress bars
"""
