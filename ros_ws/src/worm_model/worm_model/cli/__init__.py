"""What every command-line tool of the project shares.

``validate``  bad input said once: argparse types (finite, in range, with the unit), the
              one-line error parser, file readers (UTF-8, YAML/JSON without duplicate keys),
              the rig's physical envelope, outputs written atomically and never over a
              user's file without --force, and ``run_tool`` (exit 2 on bad input, no traceback)
``progress``  progress bars
"""
