"""``python -m worm_rig_driver.sim.effects``: the ``worm_effects`` executable."""
from worm_rig_driver.sim.effects.cli import main

raise SystemExit(main())
