"""Dataset readers and writers: the real Azure Kinect ToF frame (:mod:`.azure_kinect`), Middlebury
pairs (:mod:`.middlebury`), NYU Depth v2 labeled frames (:mod:`.nyuv2`; the official
``nyu_depth_v2_labeled.mat`` through :mod:`.nyuv2_mat`), the synthetic
SYNTH3-style dataset (:mod:`.synth`), synthetic labeled indoor frames (:mod:`.synth_indoor`),
SYNTH3's own MATLAB layout (:mod:`.synth3`) and rig
calibration JSON (:mod:`.calibration`)."""

from rgbd_rs.data.azure_kinect import (
    AzureKinectCalibration,
    AzureKinectFrame,
    load_azure_kinect_calibration,
    load_azure_kinect_frame,
    reproject_to_color,
)
from rgbd_rs.data.calibration import (
    load_camera,
    load_rig,
    load_stereo_rig,
    save_camera,
    save_rig,
)
from rgbd_rs.data.middlebury import MiddleburyPair, load_middlebury
from rgbd_rs.data.nyuv2 import (
    LABEL13_NAMES,
    NYUV2_CAMERA,
    NyuFrame,
    instance_ground_truth,
    load_nyuv2_frame,
    nyuv2_frames,
    region_ground_truth,
)
from rgbd_rs.data.nyuv2_mat import (
    NyuClassMapping,
    NyuMatDataset,
    NyuSplits,
    NyuTestLabels,
    load_nyuv2_mapping,
    load_nyuv2_splits,
)
from rgbd_rs.data.paths import data_root
from rgbd_rs.data.stereo_scenes import (
    StereoScene,
    load_stereo_scene,
    load_stereo_scenes,
    scene_names,
)
from rgbd_rs.data.synth import SynthDataset, SynthSample, synth3_rig, write_dataset
from rgbd_rs.data.synth3 import Synth3Dataset, Synth3Sample
from rgbd_rs.data.synth_indoor import (
    IndoorFrame,
    IndoorFrames,
    generate_indoor,
    render_indoor_frame,
)

__all__ = [
    "LABEL13_NAMES",
    "NYUV2_CAMERA",
    "AzureKinectCalibration",
    "AzureKinectFrame",
    "IndoorFrame",
    "IndoorFrames",
    "MiddleburyPair",
    "NyuClassMapping",
    "NyuFrame",
    "NyuMatDataset",
    "NyuSplits",
    "NyuTestLabels",
    "StereoScene",
    "Synth3Dataset",
    "Synth3Sample",
    "SynthDataset",
    "SynthSample",
    "data_root",
    "generate_indoor",
    "instance_ground_truth",
    "load_azure_kinect_calibration",
    "load_azure_kinect_frame",
    "load_camera",
    "load_middlebury",
    "load_nyuv2_frame",
    "load_nyuv2_mapping",
    "load_nyuv2_splits",
    "load_rig",
    "load_stereo_rig",
    "load_stereo_scene",
    "load_stereo_scenes",
    "nyuv2_frames",
    "region_ground_truth",
    "render_indoor_frame",
    "reproject_to_color",
    "save_camera",
    "save_rig",
    "scene_names",
    "synth3_rig",
    "write_dataset",
]
