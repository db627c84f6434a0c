"""Videos: off-screen rendered episodes, encoding, and videos of a result directory."""
