"""Fill a sensor_msgs/LaserScan with the 360-beam, counter-clockwise layout both LDS drivers publish."""
import math

BEAMS = 360
ANGLE_INCREMENT = 2.0 * math.pi / BEAMS


def fill_scan(message, ranges, intensities, stamp, frame_id, range_min, range_max, time_increment=0.0,
              scan_time=0.0):
    """Beam i at i degrees from the front, counter-clockwise, measured at `stamp + i * time_increment`
    (time_increment is negative for the LDS, which turn clockwise: see lds_models); 0 when unknown."""
    message.header.stamp = stamp
    message.header.frame_id = frame_id
    message.angle_min = 0.0
    message.angle_increment = ANGLE_INCREMENT
    message.angle_max = 2.0 * math.pi - ANGLE_INCREMENT
    message.range_min = range_min
    message.range_max = range_max
    message.time_increment = time_increment
    message.scan_time = scan_time
    message.ranges = list(ranges)
    message.intensities = list(intensities)
    return message
