// A sequence of LiDAR scans with known poses, read lazily from disk one scan at a time.
//
// Layouts recognised in a directory:
//   - KITTI odometry: velodyne/*.bin, poses.txt (or a pose file given explicitly), optional
//     calib.txt whose Tr turns camera poses into LiDAR poses: T_world_lidar = Tr^-1 * P * Tr.
//   - A folder of .ply or .pcd scans (in the directory or its scans/ subfolder), sorted by name,
//     with poses.txt (KITTI format) or poses_tum.txt / *.tum (TUM format) in the directory.
// Scans are sorted by file name (numerically when names are plain numbers) and matched to poses
// by index; TUM timestamps are not used for matching. DIR/calib.txt is applied to KITTI-format
// poses only; an explicit calib_path is applied to either format.
//
// Recordings (recording.hpp): a ROS 1 bag (.bag), a ROS 2 bag folder (metadata.yaml with .db3 or
// .mcap files), or a bare .db3 / .mcap file. One sensor_msgs/PointCloud2 topic is read (found
// automatically when it is the only one, else named by `topic`); the frame range selects
// messages in time order. Poses come from a TUM file (`poses_path`, required) matched by time:
// each scan's header stamp is interpolated between the two poses around it (translation linear,
// rotation slerp; a stamp equal to a pose's gives that pose exactly); a stamp outside the pose
// file's time span is a DataError naming the stamp. Only the message index is kept in memory
// (about 50 bytes a message); each load() reads and decodes one message. Opening reads every
// selected message's stamp: ROS 1 and MCAP readers keep each message's first bytes while
// indexing, SQLite reads just those bytes.
//
// Mapping without poses (the odometry estimates them): with ScanSequenceOptions::poses
// kIfPresent a directory without a pose file (or a recording without one) opens with identity
// poses and has_poses() false.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "shine/io/point_times.hpp"
#include "shine/io/sweep_times.hpp"

namespace shine {

/// One scan: points in the sensor frame and the sensor's pose in the world frame.
struct Scan {
    std::vector<Eigen::Vector3f> points_sensor;
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    std::filesystem::path source;
    /// Acquisition time of the scan in seconds (a recording's header stamp; 0 for files).
    double stamp_s = 0.0;
    /// Per-point time in seconds relative to the scan's pose (stamp_s for recordings), one per
    /// point of points_sensor; empty when the scan carries no per-point time (KITTI .bin, a PLY,
    /// PCD or PointCloud2 without a t / time / timestamp / offset_time field; point_times.hpp).
    std::vector<double> point_time_s;
    PointTimeFormat point_time_format;  ///< the field, unit and reference point_time_s came from
    /// Where the sensor was when it measured each point, in the frame of points_sensor: set when
    /// a scan is deskewed (its points moved into the sensor frame at the scan's time, while the
    /// sensor moved during the sweep); empty: at the frame's origin for every point.
    std::vector<Eigen::Vector3f> point_origin_sensor;
    /// Intensity of each point as the sensor gives it, never rescaled (a KITTI .bin's 4th
    /// column, 0..1 for KITTI's Velodyne; a uint8 field 0..255): one per point of
    /// points_sensor, or empty when the scan has none -- no intensity field, or every value 0 or
    /// not finite (a KITTI .bin written without intensity). NaN: that point's is unknown; the
    /// point is kept. Fields and rules: point_intensity.hpp.
    std::vector<float> intensity;
    std::string intensity_field;  ///< the field intensity came from ("" without one)
};

/// Whether a sequence must come with poses.
enum class PoseFileUse : std::uint8_t {
    kRequired,  ///< no pose file is an error (the default)
    kIfPresent  ///< no pose file: identity poses, has_poses() false
};

/// How to open a sequence; every member has a sensible default.
struct ScanSequenceOptions {
    std::filesystem::path poses_path;  ///< empty: found in the directory
    std::string pose_format = "auto";  ///< auto | kitti | tum
    std::filesystem::path calib_path;  ///< empty: DIR/calib.txt if present
    int first_frame = 0;               ///< first scan index used
    int last_frame = -1;               ///< last scan index used (inclusive), -1 = all
    int frame_step = 1;                ///< use every n-th scan
    std::string topic;                 ///< recordings: the PointCloud2 topic; empty: the only one
    PoseFileUse poses = PoseFileUse::kRequired;  ///< whether poses must exist
};

/// Lazily loaded scan sequence. Opening validates the layout and the pose count; scans are read
/// on demand by load(), so a long drive never has to fit in memory.
class ScanSequence {
  public:
    /// Opens `dir`. Throws IoError (missing directory, no scans, unreadable pose file), DataError
    /// (fewer poses than scans; extra poses are ignored) or ConfigError (frame range, pose
    /// format) with a message naming the path and the fix.
    static ScanSequence open(const std::filesystem::path& dir,
                             const ScanSequenceOptions& options = {});

    /// Whether `path` is read as a recording rather than a folder of scan files.
    static bool is_recording(const std::filesystem::path& path);

    std::size_t size() const { return scan_paths_.size(); }
    /// T_world_sensor of scan i (calibration applied; the identity when !has_poses()).
    const Eigen::Isometry3d& pose(std::size_t i) const { return poses_.at(i); }
    /// Whether the poses come from the data (false: identity placeholders, see PoseFileUse).
    bool has_poses() const { return has_poses_; }
    /// The same scans at `poses_world_sensor` (one per scan): batch mapping on estimated poses.
    /// Throws DataError if the count differs.
    ScanSequence with_poses(const std::vector<Eigen::Isometry3d>& poses_world_sensor) const;
    const std::filesystem::path& scan_path(std::size_t i) const { return scan_paths_.at(i); }
    const std::filesystem::path& directory() const { return dir_; }
    /// Acquisition time of scan i in seconds (recordings: header stamp; files: 0).
    double stamp_s(std::size_t i) const { return stamps_s_.empty() ? 0.0 : stamps_s_.at(i); }
    /// The position of scan i among all scans of the directory (a recording: among the topic's
    /// messages) before frame selection and subset(): frame_number(b) - frame_number(a) scan
    /// periods lie between scans a and b of a sequence without stamps.
    std::size_t frame_number(std::size_t i) const {
        return frame_numbers_.empty() ? i : frame_numbers_.at(i);
    }
    /// Whether the scans come from a recording (bag / MCAP / SQLite) rather than files.
    bool from_recording() const { return recording_ != nullptr; }
    /// Reads scan i from disk (points as stored; filtering is preprocess_scan's job). A scan
    /// without per-point times gets them from its azimuths when with_sweep_times() gave a model.
    Scan load(std::size_t i) const;
    /// The same scans, those without a time field timed by `model` (sweep_times.hpp) on load.
    ScanSequence with_sweep_times(const SweepTimeModel& model) const;
    /// Whether load() times scans without a time field from their azimuths.
    bool has_sweep_times() const { return sweep_times_.has_value(); }
    /// The model of with_sweep_times() (has_sweep_times() must be true).
    const SweepTimeModel& sweep_times() const { return *sweep_times_; }

    /// The scans `indices` of this sequence, in that order: held-out evaluation maps with some
    /// scans and scores the map on the others. Throws ConfigError for an index out of range.
    ScanSequence subset(const std::vector<std::size_t>& indices) const;

  private:
    /// load() without the sweep times.
    Scan load_as_stored(std::size_t i) const;
    struct RecordingState;  ///< the open recording, its selected messages and a lock
    static ScanSequence open_recording(const std::filesystem::path& path,
                                       const ScanSequenceOptions& options);

    std::filesystem::path dir_;
    std::vector<std::filesystem::path> scan_paths_;
    std::vector<Eigen::Isometry3d> poses_;
    bool has_poses_ = true;
    std::vector<std::size_t> frame_numbers_;     ///< see frame_number()
    std::vector<double> stamps_s_;               ///< recordings only
    std::shared_ptr<RecordingState> recording_;  ///< recordings only
    /// Recordings only, after subset(): scan i is the recording's selected message
    /// recording_index_[i] (empty: message i).
    std::vector<std::size_t> recording_index_;
    std::optional<SweepTimeModel> sweep_times_;  ///< see with_sweep_times()
};

}  // namespace shine
