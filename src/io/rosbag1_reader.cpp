// ROS 1 bag reader (format 2.0), written from the format description at
// http://wiki.ros.org/Bags/Format/2.0.
//
// A record is: header_len u32, header (fields: field_len u32, "name=value"), data_len u32, data.
// The header's `op` field gives the record type: 0x02 message data, 0x03 bag header, 0x04 index
// data, 0x05 chunk, 0x06 chunk info, 0x07 connection.
#include "shine/io/rosbag1_reader.hpp"

#include <algorithm>
#include <map>
#include <optional>

#include "recording_bytes.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace rosbag1_internal {
namespace {

using recording_internal::ByteCursor;
using recording_internal::RangedFile;

constexpr const char* kKind = "ROS 1 bag";
constexpr std::string_view kMagic = "#ROSBAG V2.0\n";
constexpr std::uint64_t kNoChunk = ~std::uint64_t{0};

constexpr std::uint8_t kOpMessage = 0x02;
constexpr std::uint8_t kOpBagHeader = 0x03;
constexpr std::uint8_t kOpIndexData = 0x04;
constexpr std::uint8_t kOpChunk = 0x05;
constexpr std::uint8_t kOpChunkInfo = 0x06;
constexpr std::uint8_t kOpConnection = 0x07;

/// The fields of a record header (or of a connection record's data, which has the same form).
using Fields = std::map<std::string, std::string, std::less<>>;

Fields parse_fields(std::string_view bytes, const fs::path& path, std::uint64_t offset) {
    Fields fields;
    ByteCursor c(bytes, path, kKind, offset);
    while (!c.at_end()) {
        const std::uint32_t len = c.u32("header field length");
        const std::string_view field = c.bytes(len, "header field");
        const std::size_t eq = field.find('=');
        if (eq == std::string_view::npos) c.fail("header field without '=' (corrupt record)");
        fields[std::string(field.substr(0, eq))] = std::string(field.substr(eq + 1));
    }
    return fields;
}

template <class T>
T field_value(const Fields& fields, const char* name, const fs::path& path, std::uint64_t offset) {
    const auto it = fields.find(name);
    if (it == fields.end() || it->second.size() != sizeof(T)) {
        throw IoError(std::string(kKind) + " '" + path.string() + "', record at byte " +
                      std::to_string(offset) + ": field '" + name +
                      (it == fields.end() ? "' is missing" : "' has the wrong size") +
                      " (corrupt record)");
    }
    T v;
    std::memcpy(&v, it->second.data(), sizeof(T));
    return v;
}

std::string field_string(const Fields& fields, const char* name, const fs::path& path,
                         std::uint64_t offset) {
    const auto it = fields.find(name);
    if (it == fields.end()) {
        throw IoError(std::string(kKind) + " '" + path.string() + "', record at byte " +
                      std::to_string(offset) + ": field '" + name +
                      "' is missing (corrupt record)");
    }
    return it->second;
}

/// One record parsed from a byte range: its header fields and where its data lies.
struct Record {
    Fields fields;
    std::uint8_t op = 0;
    std::uint64_t data_offset = 0;  ///< in the range
    std::uint32_t data_bytes = 0;
};

/// Parses the record at `c`'s position and advances past it (the data is skipped).
Record next_record(ByteCursor& c, const fs::path& path, std::uint64_t base) {
    Record r;
    const std::uint64_t start = base + c.position();
    const std::uint32_t header_len = c.u32("record header length");
    r.fields = parse_fields(c.bytes(header_len, "record header"), path, start + 4);
    r.op = field_value<std::uint8_t>(r.fields, "op", path, start);
    r.data_bytes = c.u32("record data length");
    r.data_offset = c.position();
    c.bytes(r.data_bytes, "record data");
    return r;
}

struct Connection {
    std::string topic;
    std::string type;
};

class RosBag1Reader final : public RecordingReader {
  public:
    explicit RosBag1Reader(const fs::path& path) : RecordingReader(path), file_(path, kKind) {
        if (file_.size() == 0) {
            throw IoError(std::string(kKind) + " '" + path.string() +
                          "' is empty (was the recording stopped before it wrote anything?)");
        }
        const std::string magic =
            file_.read(0, std::min<std::uint64_t>(kMagic.size(), file_.size()), "version line");
        if (magic != kMagic) {
            if (magic.rfind("#ROSBAG V", 0) == 0) {
                throw IoError(std::string(kKind) + " '" + path.string() + "' is format " +
                              printable(magic.substr(9)) +
                              "; only format 2.0 (ROS Groovy and later) is read: convert it "
                              "with `rosbag fix` or `rosbag reindex` first");
            }
            throw IoError("'" + path.string() +
                          "' is not a ROS 1 bag: it does not start with \"#ROSBAG V2.0\"");
        }
        index();
    }

    std::string kind() const override { return kKind; }

    std::vector<RecordingTopic> topics() const override {
        std::map<std::string, RecordingTopic> by_name;
        for (const auto& [id, conn] : connections_) {
            RecordingTopic& t = by_name[conn.topic];
            t.name = conn.topic;
            t.type = conn.type;
            t.encoding = MessageEncoding::kRos1;
            const auto it = messages_.find(id);
            if (it != messages_.end()) t.message_count += it->second.size();
        }
        std::vector<RecordingTopic> out;
        for (auto& [name, t] : by_name) out.push_back(t);
        return out;
    }

    std::vector<RecordingMessage> messages(const std::string& topic) const override {
        // Several connections of one topic are merged in time; ties keep file order.
        return recording_internal::topic_messages_in_time(connections_, messages_, topic);
    }

    std::string read(const RecordingMessage& m) override {
        if (m.block == kNoChunk) {
            const std::string head = file_.read(m.offset, 4, "record header length");
            std::uint32_t header_len;
            std::memcpy(&header_len, head.data(), 4);
            const std::string rec = file_.read(m.offset, 8ull + header_len, "record header");
            std::uint32_t data_len;
            std::memcpy(&data_len, rec.data() + 4 + header_len, 4);
            return file_.read(m.offset + 8 + header_len, data_len, "message data");
        }
        const std::string& chunk = load_chunk(m.block);
        ByteCursor c(chunk, path(), kKind + std::string(" chunk"), 0);
        c.bytes(m.offset, "records before the message");
        const Record r = next_record(c, path(), 0);
        return chunk.substr(static_cast<std::size_t>(r.data_offset), r.data_bytes);
    }

  private:
    static std::string printable(std::string s) {
        for (char& ch : s) {
            if (ch == '\n' || ch == '\r') ch = ' ';
        }
        while (!s.empty() && s.back() == ' ') s.pop_back();
        return "'" + s + "'";
    }

    /// The header of the record at file offset `pos`, and where its data starts in the file.
    Record record_at(std::uint64_t pos) {
        const std::string len_bytes = file_.read(pos, 4, "record header length");
        std::uint32_t header_len;
        std::memcpy(&header_len, len_bytes.data(), 4);
        const std::string head = file_.read(pos, 8ull + header_len, "record header");
        // Parse the header and data length from the bytes just read; the data is not read here.
        ByteCursor c(head, path(), kKind, pos);
        Record r;
        c.u32("record header length");
        r.fields = parse_fields(c.bytes(header_len, "record header"), path(), pos + 4);
        r.op = field_value<std::uint8_t>(r.fields, "op", path(), pos);
        r.data_bytes = c.u32("record data length");
        r.data_offset = pos + 8 + header_len;
        if (r.data_offset + r.data_bytes > file_.size()) {
            throw IoError(std::string(kKind) + " '" + path().string() + "', record at byte " +
                          std::to_string(pos) + ": truncated: its data needs " +
                          std::to_string(r.data_bytes) + " bytes, the file ends after " +
                          std::to_string(file_.size() - r.data_offset) +
                          " (is the recording complete?)");
        }
        return r;
    }

    /// The uncompressed records of the chunk record at file offset `pos` (cached).
    const std::string& load_chunk(std::uint64_t pos) {
        if (cached_chunk_pos_ == pos) return cached_chunk_;
        const Record r = record_at(pos);
        if (r.op != kOpChunk) {
            throw IoError(std::string(kKind) + " '" + path().string() + "', byte " +
                          std::to_string(pos) + ": expected a chunk record (changed file?)");
        }
        const std::string compression = field_string(r.fields, "compression", path(), pos);
        const std::uint32_t size = field_value<std::uint32_t>(r.fields, "size", path(), pos);
        const std::string data = file_.read(r.data_offset, r.data_bytes, "chunk data");
        cached_chunk_ =
            recording_internal::decompress_block(data, compression, size, path(), kKind, pos);
        cached_chunk_pos_ = pos;
        return cached_chunk_;
    }

    void add_connection(const Record& r, std::string_view data, std::uint64_t pos) {
        const std::uint32_t id = field_value<std::uint32_t>(r.fields, "conn", path(), pos);
        Connection conn;
        conn.topic = field_string(r.fields, "topic", path(), pos);
        const Fields details = parse_fields(data, path(), pos);
        conn.type = field_string(details, "type", path(), pos);
        connections_.emplace(id, std::move(conn));
    }

    void add_message(const Record& r, std::string_view data, std::uint64_t block,
                     std::uint64_t offset, std::uint64_t pos) {
        const std::uint32_t conn = field_value<std::uint32_t>(r.fields, "conn", path(), pos);
        const std::uint64_t time = field_value<std::uint64_t>(r.fields, "time", path(), pos);
        RecordingMessage m;
        // ROS time: u32 seconds then u32 nanoseconds.
        m.log_time_ns = static_cast<std::int64_t>(time & 0xffffffffu) * 1000000000 +
                        static_cast<std::int64_t>(time >> 32);
        m.block = block;
        m.offset = offset;
        m.head_bytes = static_cast<std::uint8_t>(std::min(data.size(), m.head.size()));
        if (m.head_bytes > 0) std::memcpy(m.head.data(), data.data(), m.head_bytes);
        messages_[conn].push_back(m);
    }

    /// Walks every record of the file once (see the header comment).
    void index() {
        std::uint64_t pos = kMagic.size();
        bool saw_bag_header = false;
        while (pos < file_.size()) {
            const Record r = record_at(pos);
            switch (r.op) {
                case kOpBagHeader:
                    saw_bag_header = true;
                    break;
                case kOpChunk: {
                    const std::string& chunk = load_chunk(pos);
                    ByteCursor c(chunk, path(),
                                 kKind + std::string(" chunk at byte ") + std::to_string(pos) + ",",
                                 0);
                    while (!c.at_end()) {
                        const std::uint64_t inner = c.position();
                        const Record in = next_record(c, path(), 0);
                        if (in.op == kOpConnection) {
                            add_connection(
                                in, std::string_view(chunk).substr(in.data_offset, in.data_bytes),
                                pos);
                        } else if (in.op == kOpMessage) {
                            add_message(
                                in, std::string_view(chunk).substr(in.data_offset, in.data_bytes),
                                pos, inner, pos);
                        } else {
                            c.fail("unexpected record type " + std::to_string(in.op) +
                                   " inside a chunk (corrupt chunk)");
                        }
                    }
                    break;
                }
                case kOpConnection:
                    add_connection(r, file_.read(r.data_offset, r.data_bytes, "connection"), pos);
                    break;
                case kOpMessage:
                    add_message(r, {}, kNoChunk, pos, pos);
                    break;
                case kOpIndexData:
                case kOpChunkInfo:
                    break;  // the walk finds every message without the index
                default:
                    throw IoError(std::string(kKind) + " '" + path().string() + "', byte " +
                                  std::to_string(pos) + ": unknown record type " +
                                  std::to_string(r.op) + " (corrupt file)");
            }
            pos = r.data_offset + r.data_bytes;
        }
        if (!saw_bag_header) {
            throw IoError(std::string(kKind) + " '" + path().string() +
                          "' has no bag header record (truncated or corrupt)");
        }
        for (const auto& [id, list] : messages_) {
            if (connections_.find(id) == connections_.end()) {
                throw IoError(std::string(kKind) + " '" + path().string() +
                              "': messages of connection " + std::to_string(id) +
                              " have no connection record (corrupt file)");
            }
        }
    }

    RangedFile file_;
    std::map<std::uint32_t, Connection> connections_;
    std::map<std::uint32_t, std::vector<RecordingMessage>> messages_;
    std::uint64_t cached_chunk_pos_ = kNoChunk;
    std::string cached_chunk_;
};

}  // namespace
}  // namespace rosbag1_internal

std::unique_ptr<RecordingReader> open_rosbag1(const fs::path& path) {
    return std::make_unique<rosbag1_internal::RosBag1Reader>(path);
}

}  // namespace shine
