"""The simulated rig: ``plant``, ``sensors``, ``effects`` (plug-ins), ``simulated_rig`` (plant +
effects + sensors on the sample clock; read it first), ``virtual_rig`` (behind a pty). Plain numpy."""
