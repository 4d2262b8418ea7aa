"""Motion and safety: mode arbitration, safety latches, velocity validation, odometry, chassis driver interface."""
