// Recordings: ROS 1 bags, ROS 2 bags (SQLite .db3 or MCAP files) and bare MCAP / SQLite files,
// read as an index of messages per topic plus one message at a time, so that memory does not grow
// with the recording's length (docs/recordings.md).
//
// Recognised by content first, extension second:
//   - "#ROSBAG V2.0\n" at the start: a ROS 1 bag (chunks uncompressed, bz2 or lz4 frames);
//   - "\x89MCAP0\r\n" at the start: an MCAP file (chunks none, lz4 frames or zstd);
//   - "SQLite format 3\0" at the start: a rosbag2 SQLite file (tables topics and messages);
//   - a directory with metadata.yaml: a ROS 2 bag whose relative_file_paths are read in order.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace shine {

/// How the messages of a topic are serialised.
enum class MessageEncoding {
    kRos1,  ///< ROS 1 serialisation (little-endian, no alignment)
    kCdr,   ///< OMG CDR with its 4-byte encapsulation header (ROS 2)
};

/// A topic of a recording with its message count.
struct RecordingTopic {
    std::string name;
    std::string type;  ///< "sensor_msgs/msg/PointCloud2" (ROS 2) or "sensor_msgs/PointCloud2"
    std::size_t message_count = 0;
    MessageEncoding encoding = MessageEncoding::kCdr;
};

/// Where one message is: the reader-specific locator and its receive (log) time.
struct RecordingMessage {
    std::int64_t log_time_ns = 0;
    std::uint64_t block = 0;   ///< ROS 1 / MCAP: chunk file offset; SQLite: file number
    std::uint64_t offset = 0;  ///< ROS 1 / MCAP: offset in the chunk; SQLite: row id
    std::uint32_t file = 0;    ///< which file of a ROS 2 bag of several files
    /// The message's first bytes when the reader saw them while indexing (ROS 1, MCAP: the
    /// header stamp is there), so that stamps need no second pass over compressed chunks.
    std::array<char, 16> head{};
    std::uint8_t head_bytes = 0;
};

/// A recording opened for indexed, one-message-at-a-time reading.
class RecordingReader {
  public:
    virtual ~RecordingReader() = default;
    /// "ROS 1 bag", "MCAP file", "ROS 2 SQLite bag"...
    virtual std::string kind() const = 0;
    const std::filesystem::path& path() const { return path_; }
    /// Topics in name order, with message counts.
    virtual std::vector<RecordingTopic> topics() const = 0;
    /// The messages of `topic` in log-time order (ties in file order).
    virtual std::vector<RecordingMessage> messages(const std::string& topic) const = 0;
    /// The serialised bytes of one message (reads and decompresses at most one chunk; the last
    /// chunk is kept, so reading messages in order decompresses each chunk once).
    virtual std::string read(const RecordingMessage& message) = 0;
    /// At least the first `bytes` bytes of a message (all of it if shorter); readers that can read
    /// a prefix without the rest (SQLite) do.
    virtual std::string read_prefix(const RecordingMessage& message, std::size_t bytes) {
        if (bytes <= message.head_bytes) return std::string(message.head.data(), bytes);
        return read(message);
    }

  protected:
    explicit RecordingReader(std::filesystem::path path) : path_(std::move(path)) {}

  private:
    std::filesystem::path path_;
};

/// Whether `path` looks like a recording (by content, then extension or metadata.yaml).
bool is_recording_path(const std::filesystem::path& path);

/// Opens a recording and indexes its messages. Throws IoError naming the file and the problem
/// (missing, empty, truncated, corrupt, unsupported version or compression).
std::unique_ptr<RecordingReader> open_recording(const std::filesystem::path& path);

/// The PointCloud2 topic to read: `requested` if given (DataError listing the topics when it is
/// not in the recording or not a PointCloud2), else the only PointCloud2 topic (DataError listing
/// topics, types and message counts when there is none or several: name one with --topic).
RecordingTopic select_point_cloud_topic(const RecordingReader& reader,
                                        const std::string& requested);

/// Whether `type` names sensor_msgs/PointCloud2 (ROS 1 or ROS 2 spelling).
bool is_point_cloud2_type(const std::string& type);

}  // namespace shine
