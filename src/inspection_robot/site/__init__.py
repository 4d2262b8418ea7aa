"""The site file: its template, loading, and the check robot.launch runs before any node starts."""
