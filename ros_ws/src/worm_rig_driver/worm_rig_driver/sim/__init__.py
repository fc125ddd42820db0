"""The simulated rig: ``plant`` (motor + worm gearbox + load motors), ``sensors`` (ADC chain,
tachos, encoders), ``effects`` (what the model lacks, as plug-ins; a folder:
its own map), ``simulated_rig`` (plant +
effects + sensors on the sample clock; read it first), ``virtual_rig`` (behind a pty speaking
the firmware's protocol). Vectorised numpy over rigs; one live rig takes the scalar twins
``scalar_plant`` and ``scalar_sensors`` (plain float math, equal to round-off)."""
