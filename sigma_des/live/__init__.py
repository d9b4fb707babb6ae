"""Live mode: the scenario run by real processes over a real Mosquitto broker.

``broker`` starts and stops a private Mosquitto; ``wire`` is the topic scheme and
binary payload codec; ``shim`` applies the scenario's link impairments in the
client; ``loop`` is the small timer + inbox loop every live process runs;
``host`` is a physics host process; ``server`` the alignment server (trigger
source, aligner, behaviour, renderer sampling); ``runner`` runs one method after
another and returns the same :class:`~sigma_des.api.Results` as ``compare``;
``cli`` holds the ``live`` subcommand. Calibration is :mod:`sigma_des.calibrate`.
"""
