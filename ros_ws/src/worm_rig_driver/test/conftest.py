"""worm_rig_driver's tests may use worm_model's test fixtures (``fixtures.<module>``, e.g. bags laid out as
each rosbag2 release writes them): that folder goes on sys.path, since pytest's importlib mode puts none there."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "worm_model" / "test"))
