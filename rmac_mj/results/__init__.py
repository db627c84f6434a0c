"""The result directory: its layout and store, integrity checks, snapshots, atomic files."""
