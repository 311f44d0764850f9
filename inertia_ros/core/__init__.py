"""Pure numpy/scipy core: no ROS, no MCAP.  Time is float seconds, everything SI."""
