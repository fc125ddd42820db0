"""What every command-line tool of the project shares: progress bars (``progress``)."""
