"""Camera-range calibration maths of IHRCF (Sefidgar & Landry 2022, sections 2.1 and 2.2).

Pure numpy/scipy/cv2 (no simulator), split by job: ``segmentation`` (colour pads, eq. 2-7 and
Table 1), ``tables`` (range -> pixel PCHIP tables), ``chessboard`` (intrinsics for ATDA) and
``file`` (the versioned calibration file).
"""

from ihrcf_env.core.calibration.chessboard import (
    IntrinsicsResult,
    calibrate_intrinsics,
    chessboard_object_points,
    find_chessboard,
)
from ihrcf_env.core.calibration.file import (
    FORMAT_VERSION,
    Calibration,
    CalibrationError,
    default_calibration_path,
)
from ihrcf_env.core.calibration.segmentation import (
    YCBCR_MATRIX,
    YCBCR_OFFSET,
    YCBCR_THRESHOLDS,
    PadDetection,
    colour_mask,
    rgb_to_ycbcr,
    segment_mask,
    segment_pad,
    segment_pads,
    ycbcr_mask,
)
from ihrcf_env.core.calibration.tables import SENSOR_NAMES, RangePixelTable, SensorTable

__all__ = [
    "FORMAT_VERSION",
    "SENSOR_NAMES",
    "YCBCR_MATRIX",
    "YCBCR_OFFSET",
    "YCBCR_THRESHOLDS",
    "Calibration",
    "CalibrationError",
    "IntrinsicsResult",
    "PadDetection",
    "RangePixelTable",
    "SensorTable",
    "calibrate_intrinsics",
    "chessboard_object_points",
    "colour_mask",
    "default_calibration_path",
    "find_chessboard",
    "rgb_to_ycbcr",
    "segment_mask",
    "segment_pad",
    "segment_pads",
    "ycbcr_mask",
]
