"""health: watching the gearbox from its own signals, in a check and live, over its life (no ROS).

Map (dependencies point up this list):

==============  ==============================================================
``model``       what wears, in the model: the drive's steady friction torque with mu's
                scale, speed and load laws, the drive- and gear-side drags; mu's
                temperature law
``settings``    priors, alarm limits, the thermal model's and the live window's
                settings (one optional YAML file)
``blocks``      samples reduced to 50 ms blocks (from a recorded run, or n rigs side
                by side)
``points``      steady constant-speed points from blocks
``fit``         a check's fit: the health parameters with intervals, the backlash
                from the transmission error
``thermal``     the oil temperature of a drive without a sensor, from its own losses
``record``      a check's record and the gearbox's trend file (JSON Lines)
``assess``      the baseline, mu's learned temperature law, the verdict on a check
                and on the trend
``bound``       the least uncertainty any comparison of a check with the earlier ones can
                have, and the chance one check finds a rise (a Cramér–Rao bound)
``live``        the live monitor's core: a sliding window over the stream
``plots``       the trend with its alarm bands
==============  ==============================================================

Read first: ``model`` (what is watched), then ``assess`` (how a change becomes an alarm).
"""
