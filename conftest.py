"""What every test of the repository shares (the rootdir of pytest.ini).

Ctrl-C reaches the tools the tests start, even when the test run itself was started in the background with
SIGINT ignored (worm_model.cli.errors.restore_ctrl_c): tests interrupt tools as a user's Ctrl-C does.
"""
from worm_model.cli.errors import restore_ctrl_c

restore_ctrl_c()
