"""Dataset readers and writers. See :mod:`rgbd_rs.data.azure_kinect` for the real ToF frame."""

from rgbd_rs.data.azure_kinect import (
    AzureKinectCalibration,
    AzureKinectFrame,
    load_azure_kinect_calibration,
    load_azure_kinect_frame,
    reproject_to_color,
)
from rgbd_rs.data.paths import data_root

__all__ = [
    "AzureKinectCalibration",
    "AzureKinectFrame",
    "data_root",
    "load_azure_kinect_calibration",
    "load_azure_kinect_frame",
    "reproject_to_color",
]
