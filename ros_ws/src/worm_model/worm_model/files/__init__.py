"""A user's files: ``reading`` (text, YAML and JSON with every refusal one clear line) and ``writing``
(outputs replaced only with ``--force``, written atomically)."""
