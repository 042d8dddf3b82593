/* drivers/camera_v4l2.h — the V4L2 camera backend: raw ioctls, no libv4l2, single-planar MMAP streaming.
 *
 * Open by node (cfg.device, best a /dev/v4l/by-id path) or, with cfg.device NULL, by scanning /dev/video0..63 for
 * a node whose VIDIOC_QUERYCAP card and/or bus_info equal cfg.card / cfg.bus_info. The node must have
 * V4L2_CAP_VIDEO_CAPTURE and V4L2_CAP_STREAMING (device_caps when given); -ENOTTY otherwise, naming the node.
 *
 * Format: enumerated with ENUM_FMT / ENUM_FRAMESIZES and chosen by v4l2_util_choose_format/_size (YUV/RGB and
 * compressed formats refused with the reason). Raw Bayer formats (SRGGB8 ... SBGGR16, S*10P) are taken when asked
 * for, or, with no format asked, when the device offers no monochrome one (a colour sensor): most bits first; the
 * frames stay raw mosaics (camera_frame.pixfmt names the filter order). S_FMT's answer is checked (a driver that
 * changes the format or size is an error, not a surprise), its bytesperline honoured; frame interval with S_PARM
 * when the driver has V4L2_CAP_TIMEPERFRAME.
 * Exposure: V4L2_CID_EXPOSURE_AUTO set to manual, then V4L2_CID_EXPOSURE_ABSOLUTE in 100 µs units (the value is
 * rounded to the nearest 100 µs, at least 1 unit, and the applied value is read back). Gain: V4L2_CID_AUTOGAIN
 * off when the device has it (else the gain read back is the automatic one), then V4L2_CID_GAIN, or
 * V4L2_CID_ANALOGUE_GAIN when the first is absent. Trigger profile: each named control is found with
 * VIDIOC_QUERY_EXT_CTRL (names compared as v4l2_util_ctrl_name_eq) and set with VIDIOC_S_EXT_CTRLS.
 *
 * Streaming: REQBUFS(cfg.buffer_count, default 4) → QUERYBUF/mmap/QBUF → STREAMON; each frame is DQBUF'd,
 * unpacked once from the mmap buffer into the caller's camera_frame, and QBUF'd back at once. poll() gives the
 * timeout; POLLERR without a buffer is a device error. -ENODEV (unplugged) is reported as such; camera_recover
 * closes everything, reopens the same path (or card/bus match), reapplies format, exposure, gain and trigger
 * profile, and restarts streaming if it was on.
 *
 * backend_options: NULL, or a const v4l2_util_sys * to run against a fake kernel in tests.
 */
#ifndef SCICAP_DRIVERS_CAMERA_V4L2_H
#define SCICAP_DRIVERS_CAMERA_V4L2_H

#include "drivers/camera.h"

extern const camera_ops camera_v4l2_ops;

#endif
