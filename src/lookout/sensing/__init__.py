"""A vessel's sensors as a suite: position references, gyrocompasses, speed sensors
and an IMU, each at its lever arm, each with its failures, and the stage that combines
the references into the one position and heading an observer of the papers reads.

A scenario file names each sensor in a ``[sensors.NAME]`` table (its ``kind`` one of
``lookout components instrument``) with an optional list of ``[[sensors.NAME.failures]]``,
and the combining stage in ``[references]``; :class:`SensorSuite` is the sensor the
engine samples.
"""
