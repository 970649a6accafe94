"""Viewing recordings in Rerun: a :class:`~kilobot_twin.recording.swarm_data.SwarmRecording` ->
an ``.rrd`` (:mod:`.rerun_view`, the only module that imports ``rerun``)."""
