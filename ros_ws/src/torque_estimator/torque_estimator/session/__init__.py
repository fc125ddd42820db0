"""A session with the rig: what calibration (``calibrate --live``), identification (``identify``) and the health
check share when they drive it, so that each keeps only what to measure and what to fit.

==================  ===========================================================
``topics``          the rig's topics a session commands and listens to (relative names)
``resume``          the rule every resumable journal keeps: an interrupted run is continued only when
                    asked (``--resume``) and only under the same settings, naming the first that differs
``recording``       walking a timeline of set-points on the rig's sample clock, recording every sample,
                    and its resumable journal (identification's excitation, the health check's reference run)
``rig_session_node`` the client node on the graph (RigClient) and the session around it: wait for the
                    rig and controller_node, spin, and command the rig to rest on every exit
``recording_node``  ``recording``'s ROS shell: the timeline's set-points out, /rig/samples in, as a node
                    named by the session (``identify``, ``health_check``)
==================  ===========================================================
"""
