"""Compatibility alias: the file readers and writers live in :mod:`rgbd_rs.io`."""

from rgbd_rs.io import read_json, read_npz, read_png, sha256, write_json, write_npz, write_png

__all__ = ["read_json", "read_npz", "read_png", "sha256", "write_json", "write_npz", "write_png"]
