"""worm_model's tests import their fixtures as ``fixtures.<module>`` (test/fixtures/): the folder that holds
this file goes on sys.path, since pytest's importlib mode puts no test folder there itself."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
