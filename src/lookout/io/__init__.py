"""Input and output of sensor data: NMEA 0183, local coordinates, logs."""

from lookout.io.geodesy import LocalFrame as LocalFrame
from lookout.io.nmea import NmeaParser as NmeaParser
from lookout.io.nmea import Reading as Reading
