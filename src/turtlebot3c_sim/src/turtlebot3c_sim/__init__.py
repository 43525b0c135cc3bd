"""Kinematic TurtleBot3 simulator, fake OpenCR board and fake LDS-01/LDS-02 LIDARs (never shipped)."""
