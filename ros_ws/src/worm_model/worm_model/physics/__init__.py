"""The gearbox model (physics.md, paper Eqs 19-30): plain numpy, vectorised over samples.

``units`` and ``parameters`` (the rig file) come first; ``friction`` (mu models),
``modes`` (frame of motion, mode, flank), ``efficiency``, ``internal_forces``
(Eqs 21-23), ``dynamics`` (Eqs 26-28), ``motor`` (Eq 29), ``gear_side`` (load
motors' drag) and ``steady_state`` build on them; ``envelope`` is what a rig can physically do
(the bounds measured data is checked against); ``resolution`` what its sensors resolve (standstill,
sliding speed and one current sample's spread, from the rig file's ``sensors:``).
"""
