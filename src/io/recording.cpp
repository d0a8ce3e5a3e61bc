// Recordings: format recognition, ROS 2 bag folders (metadata.yaml), topic selection.
#include "shine/io/recording.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>

#include "shine/core/error.hpp"
#include "shine/io/mcap_reader.hpp"
#include "shine/io/rosbag1_reader.hpp"
#include "shine/io/rosbag2_sqlite_reader.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace recording_internal {
namespace {

enum class Format { kNone, kRos1, kMcap, kSqlite };

std::string lower_extension(const fs::path& p) {
    std::string ext = p.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

/// The format by content (the first bytes), else by extension.
Format detect_file_format(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    char head[16] = {};
    in.read(head, sizeof(head));
    const std::string magic(head, static_cast<std::size_t>(in.gcount()));
    if (magic.rfind("#ROSBAG", 0) == 0) return Format::kRos1;
    if (magic.rfind(std::string("\x89MCAP", 5), 0) == 0) return Format::kMcap;
    if (magic.rfind("SQLite format 3", 0) == 0) return Format::kSqlite;
    const std::string ext = lower_extension(path);
    if (ext == ".bag") return Format::kRos1;
    if (ext == ".mcap") return Format::kMcap;
    if (ext == ".db3") return Format::kSqlite;
    return Format::kNone;
}

std::unique_ptr<RecordingReader> open_file(const fs::path& path) {
    switch (detect_file_format(path)) {
        case Format::kRos1:
            return open_rosbag1(path);
        case Format::kMcap:
            return open_mcap(path);
        case Format::kSqlite:
            return open_rosbag2_sqlite(path);
        case Format::kNone:
            break;
    }
    throw IoError("'" + path.string() +
                  "' is not a recording: expected a ROS 1 bag (.bag), an MCAP file (.mcap) or a "
                  "ROS 2 SQLite bag (.db3)");
}

/// The files of a ROS 2 bag, in the order its metadata.yaml lists them.
std::vector<fs::path> ros2_bag_files(const fs::path& dir) {
    const fs::path meta = dir / "metadata.yaml";
    std::vector<fs::path> files;
    try {
        const YAML::Node root = YAML::LoadFile(meta.string());
        const YAML::Node info = root["rosbag2_bagfile_information"];
        if (!info || !info.IsMap()) {
            throw IoError("'" + meta.string() +
                          "' has no rosbag2_bagfile_information map: is this a ROS 2 bag?");
        }
        const YAML::Node compression = info["compression_format"];
        if (compression && compression.IsScalar() && !compression.as<std::string>().empty()) {
            throw IoError("ROS 2 bag '" + dir.string() + "' is compressed as a whole ('" +
                          compression.as<std::string>() +
                          "'): decompress it first with `ros2 bag decompress`, or record with "
                          "MCAP's own chunk compression");
        }
        const YAML::Node paths = info["relative_file_paths"];
        if (!paths || !paths.IsSequence() || paths.size() == 0) {
            throw IoError("'" + meta.string() +
                          "' lists no relative_file_paths: the bag holds no storage files");
        }
        for (const YAML::Node& p : paths) files.push_back(dir / p.as<std::string>());
    } catch (const YAML::Exception& e) {
        throw IoError("'" + meta.string() + "' is not valid rosbag2 metadata: " + e.what());
    }
    for (const fs::path& f : files) {
        std::error_code ec;
        if (!fs::is_regular_file(f, ec)) {
            throw IoError("ROS 2 bag '" + dir.string() + "': '" + f.filename().string() +
                          "', listed in metadata.yaml, does not exist");
        }
    }
    return files;
}

/// Several files of one ROS 2 bag read as one recording.
class CombinedRecording final : public RecordingReader {
  public:
    CombinedRecording(const fs::path& path, std::vector<std::unique_ptr<RecordingReader>> files)
        : RecordingReader(path), files_(std::move(files)) {}

    std::string kind() const override { return "ROS 2 bag (" + files_.front()->kind() + "s)"; }

    std::vector<RecordingTopic> topics() const override {
        std::map<std::string, RecordingTopic> by_name;
        for (const auto& f : files_) {
            for (const RecordingTopic& t : f->topics()) {
                auto [it, added] = by_name.emplace(t.name, t);
                if (!added) it->second.message_count += t.message_count;
            }
        }
        std::vector<RecordingTopic> out;
        for (auto& [name, t] : by_name) out.push_back(t);
        return out;
    }

    std::vector<RecordingMessage> messages(const std::string& topic) const override {
        std::vector<RecordingMessage> out;
        for (std::size_t i = 0; i < files_.size(); ++i) {
            for (RecordingMessage m : files_[i]->messages(topic)) {
                m.file = static_cast<std::uint32_t>(i);
                out.push_back(m);
            }
        }
        std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
            return a.log_time_ns < b.log_time_ns;
        });
        return out;
    }

    std::string read(const RecordingMessage& m) override { return files_.at(m.file)->read(m); }
    std::string read_prefix(const RecordingMessage& m, std::size_t bytes) override {
        return files_.at(m.file)->read_prefix(m, bytes);
    }

  private:
    std::vector<std::unique_ptr<RecordingReader>> files_;
};

}  // namespace
}  // namespace recording_internal

bool is_recording_path(const fs::path& path) {
    using namespace recording_internal;
    std::error_code ec;
    if (fs::is_directory(path, ec)) return fs::is_regular_file(path / "metadata.yaml", ec);
    if (!fs::is_regular_file(path, ec)) {
        const std::string ext = lower_extension(path);
        return ext == ".bag" || ext == ".mcap" || ext == ".db3";
    }
    return detect_file_format(path) != Format::kNone;
}

std::unique_ptr<RecordingReader> open_recording(const fs::path& path) {
    using namespace recording_internal;
    std::error_code ec;
    if (!fs::exists(path, ec)) {
        throw IoError("recording '" + path.string() + "' does not exist");
    }
    if (!fs::is_directory(path, ec)) return open_file(path);
    const std::vector<fs::path> files = ros2_bag_files(path);
    std::vector<std::unique_ptr<RecordingReader>> readers;
    for (const fs::path& f : files) readers.push_back(open_file(f));
    if (readers.size() == 1) return std::move(readers.front());
    return std::make_unique<CombinedRecording>(path, std::move(readers));
}

bool is_point_cloud2_type(const std::string& type) {
    return type == "sensor_msgs/msg/PointCloud2" || type == "sensor_msgs/PointCloud2";
}

RecordingTopic select_point_cloud_topic(const RecordingReader& reader,
                                        const std::string& requested) {
    const std::vector<RecordingTopic> topics = reader.topics();
    std::string listing;
    for (const RecordingTopic& t : topics) {
        listing += "\n  " + t.name + "  " + (t.type.empty() ? "(no type)" : t.type) + "  " +
                   std::to_string(t.message_count) + " messages";
    }
    if (topics.empty()) listing = " (none)";
    const std::string where = reader.kind() + " '" + reader.path().string() + "'";
    if (!requested.empty()) {
        for (const RecordingTopic& t : topics) {
            if (t.name != requested) continue;
            if (!is_point_cloud2_type(t.type)) {
                throw DataError(where + ": topic '" + requested + "' is of type '" + t.type +
                                "', not sensor_msgs/PointCloud2; its topics:" + listing);
            }
            if (t.message_count == 0) {
                throw DataError(where + ": topic '" + requested + "' has no messages");
            }
            return t;
        }
        throw DataError(where + " has no topic '" + requested + "'; its topics:" + listing);
    }
    std::vector<RecordingTopic> clouds;
    for (const RecordingTopic& t : topics) {
        if (is_point_cloud2_type(t.type) && t.message_count > 0) clouds.push_back(t);
    }
    if (clouds.empty()) {
        throw DataError(where + " has no sensor_msgs/PointCloud2 messages; its topics:" + listing);
    }
    if (clouds.size() > 1) {
        throw DataError(where + " has " + std::to_string(clouds.size()) +
                        " PointCloud2 topics: choose one with --topic NAME; its topics:" + listing);
    }
    return clouds.front();
}

}  // namespace shine
