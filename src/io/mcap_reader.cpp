// MCAP reader, written from the specification at https://mcap.dev/spec (version 0).
//
// Records: opcode u8, body length u64, body. Strings are u32 length + bytes, byte arrays u32
// length + bytes, maps u32 byte length + entries. Opcodes used here: 0x01 Header, 0x02 Footer,
// 0x03 Schema, 0x04 Channel, 0x05 Message, 0x06 Chunk, 0x0F Data End; the others (indexes,
// statistics, attachments, metadata, summary offsets) are skipped.
#include "shine/io/mcap_reader.hpp"

#include <zlib.h>

#include <algorithm>
#include <map>

#include "recording_bytes.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace mcap_internal {
namespace {

using recording_internal::ByteCursor;
using recording_internal::RangedFile;

constexpr const char* kKind = "MCAP file";
constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);
constexpr std::uint64_t kNoChunk = ~std::uint64_t{0};

constexpr std::uint8_t kOpHeader = 0x01;
constexpr std::uint8_t kOpFooter = 0x02;
constexpr std::uint8_t kOpSchema = 0x03;
constexpr std::uint8_t kOpChannel = 0x04;
constexpr std::uint8_t kOpMessage = 0x05;
constexpr std::uint8_t kOpChunk = 0x06;

std::string_view read_string(ByteCursor& c, const char* what) {
    const std::uint32_t n = c.u32(what);
    return c.bytes(n, what);
}

struct Channel {
    std::uint16_t schema_id = 0;
    std::string topic;
    std::string message_encoding;
};

class McapReader final : public RecordingReader {
  public:
    explicit McapReader(const fs::path& path) : RecordingReader(path), file_(path, kKind) {
        if (file_.size() == 0) {
            throw IoError(std::string(kKind) + " '" + path.string() +
                          "' is empty (was the recording stopped before it wrote anything?)");
        }
        const std::string magic =
            file_.read(0, std::min<std::uint64_t>(kMagic.size(), file_.size()), "magic");
        if (magic != kMagic) {
            throw IoError("'" + path.string() +
                          "' is not an MCAP file: it does not start with the MCAP magic "
                          "\\x89MCAP0\\r\\n");
        }
        index();
    }

    std::string kind() const override { return kKind; }

    std::vector<RecordingTopic> topics() const override {
        std::map<std::string, RecordingTopic> by_name;
        for (const auto& [id, ch] : channels_) {
            RecordingTopic& t = by_name[ch.topic];
            t.name = ch.topic;
            const auto s = schema_names_.find(ch.schema_id);
            t.type = s == schema_names_.end() ? std::string() : s->second;
            t.encoding =
                ch.message_encoding == "ros1" ? MessageEncoding::kRos1 : MessageEncoding::kCdr;
            const auto it = messages_.find(id);
            if (it != messages_.end()) t.message_count += it->second.size();
        }
        std::vector<RecordingTopic> out;
        for (auto& [name, t] : by_name) out.push_back(t);
        return out;
    }

    std::vector<RecordingMessage> messages(const std::string& topic) const override {
        // Several channels of one topic are merged in time; ties keep file order.
        return recording_internal::topic_messages_in_time(channels_, messages_, topic);
    }

    std::string read(const RecordingMessage& m) override {
        if (m.block == kNoChunk) {
            const std::string head = file_.read(m.offset, 9, "record header");
            std::uint64_t len;
            std::memcpy(&len, head.data() + 1, 8);
            const std::string body = file_.read(m.offset + 9, len, "message record");
            return std::string(message_data(body, m.offset + 9));
        }
        const std::string& chunk = load_chunk(m.block);
        ByteCursor c(chunk, path(), kKind + std::string(" chunk"), 0);
        c.bytes(m.offset, "records before the message");
        c.u8("opcode");
        const std::uint64_t len = c.u64("record length");
        return std::string(message_data(c.bytes(len, "message record"), 0));
    }

  private:
    std::string_view message_data(std::string_view body, std::uint64_t offset) {
        ByteCursor c(body, path(), kKind, offset);
        c.u16("channel id");
        c.u32("sequence");
        c.u64("log time");
        c.u64("publish time");
        return c.rest();
    }

    /// The chunk record at file offset `pos`, decompressed (cached).
    const std::string& load_chunk(std::uint64_t pos) {
        if (cached_chunk_pos_ == pos) return cached_chunk_;
        const std::string head = file_.read(pos, 9, "record header");
        std::uint64_t len;
        std::memcpy(&len, head.data() + 1, 8);
        if (static_cast<std::uint8_t>(head[0]) != kOpChunk) {
            throw IoError(std::string(kKind) + " '" + path().string() + "', byte " +
                          std::to_string(pos) + ": expected a chunk record (changed file?)");
        }
        const std::string body = file_.read(pos + 9, len, "chunk record");
        ByteCursor c(body, path(), kKind, pos + 9);
        c.u64("message start time");
        c.u64("message end time");
        const std::uint64_t uncompressed_size = c.u64("uncompressed size");
        const std::uint32_t crc = c.u32("uncompressed crc");
        const std::string compression(read_string(c, "compression"));
        const std::uint64_t records_len = c.u64("records length");
        const std::string_view records = c.bytes(records_len, "chunk records");
        cached_chunk_pos_ = kNoChunk;
        cached_chunk_ = recording_internal::decompress_block(records, compression,
                                                             uncompressed_size, path(), kKind, pos);
        // CRC-32 of the uncompressed records; 0 means the writer did not compute it.
        if (crc != 0) {
            const uLong actual = crc32_z(0L, reinterpret_cast<const Bytef*>(cached_chunk_.data()),
                                         cached_chunk_.size());
            if (actual != crc) {
                throw IoError(std::string(kKind) + " '" + path().string() + "', chunk at byte " +
                              std::to_string(pos) + ": CRC mismatch (the chunk is corrupt)");
            }
        }
        cached_chunk_pos_ = pos;
        return cached_chunk_;
    }

    void add_schema(std::string_view body, std::uint64_t offset) {
        ByteCursor c(body, path(), kKind, offset);
        const std::uint16_t id = c.u16("schema id");
        const std::string name(read_string(c, "schema name"));
        if (id == 0) c.fail("schema id 0 is reserved (corrupt schema record)");
        schema_names_[id] = name;
    }

    void add_channel(std::string_view body, std::uint64_t offset) {
        ByteCursor c(body, path(), kKind, offset);
        const std::uint16_t id = c.u16("channel id");
        Channel ch;
        ch.schema_id = c.u16("schema id");
        ch.topic = std::string(read_string(c, "topic"));
        ch.message_encoding = std::string(read_string(c, "message encoding"));
        channels_[id] = std::move(ch);
    }

    void add_message(std::string_view body, std::uint64_t offset, std::uint64_t block,
                     std::uint64_t record_pos) {
        ByteCursor c(body, path(), kKind, offset);
        const std::uint16_t channel = c.u16("channel id");
        c.u32("sequence");
        const std::uint64_t log_time = c.u64("log time");
        c.u64("publish time");
        const std::string_view data = c.rest();
        RecordingMessage m;
        m.log_time_ns = static_cast<std::int64_t>(log_time);
        m.block = block;
        m.offset = record_pos;
        m.head_bytes = static_cast<std::uint8_t>(std::min(data.size(), m.head.size()));
        if (m.head_bytes > 0) std::memcpy(m.head.data(), data.data(), m.head_bytes);
        messages_[channel].push_back(m);
    }

    void index() {
        std::uint64_t pos = kMagic.size();
        bool footer = false;
        while (!footer) {
            if (pos == file_.size()) {
                throw IoError(std::string(kKind) + " '" + path().string() +
                              "' ends without a footer record: truncated (was the recording "
                              "stopped before it was closed?)");
            }
            const std::string head = file_.read(pos, 9, "record header");
            const std::uint8_t op = static_cast<std::uint8_t>(head[0]);
            std::uint64_t len;
            std::memcpy(&len, head.data() + 1, 8);
            const std::uint64_t body_pos = pos + 9;
            if (len > file_.size() - std::min(file_.size(), body_pos)) {
                throw IoError(std::string(kKind) + " '" + path().string() + "', byte " +
                              std::to_string(pos) + ": truncated: record " + std::to_string(op) +
                              " needs " + std::to_string(len) +
                              " bytes, the file ends sooner (is the recording complete?)");
            }
            switch (op) {
                case kOpSchema:
                case kOpChannel:
                case kOpMessage: {
                    const std::string body = file_.read(body_pos, len, "record");
                    if (op == kOpSchema) add_schema(body, body_pos);
                    if (op == kOpChannel) add_channel(body, body_pos);
                    if (op == kOpMessage) add_message(body, body_pos, kNoChunk, pos);
                    break;
                }
                case kOpChunk: {
                    const std::string& chunk = load_chunk(pos);
                    ByteCursor c(chunk, path(),
                                 kKind + std::string(" chunk at byte ") + std::to_string(pos) + ",",
                                 0);
                    while (!c.at_end()) {
                        const std::uint64_t inner = c.position();
                        const std::uint8_t in_op = c.u8("opcode");
                        const std::uint64_t in_len = c.u64("record length");
                        const std::string_view body = c.bytes(in_len, "record");
                        if (in_op == kOpSchema) add_schema(body, 0);
                        if (in_op == kOpChannel) add_channel(body, 0);
                        if (in_op == kOpMessage) add_message(body, 0, pos, inner);
                    }
                    break;
                }
                case kOpFooter:
                    footer = true;
                    break;
                case 0x00:
                    throw IoError(std::string(kKind) + " '" + path().string() + "', byte " +
                                  std::to_string(pos) + ": opcode 0 is invalid (corrupt file)");
                default:
                    break;  // Header, indexes, statistics, attachments, metadata, Data End
            }
            pos = body_pos + len;
        }
        const std::string tail = file_.read(pos, kMagic.size(), "closing magic");
        if (tail != kMagic) {
            throw IoError(std::string(kKind) + " '" + path().string() + "', byte " +
                          std::to_string(pos) +
                          ": the footer is not followed by the MCAP magic "
                          "(corrupt file)");
        }
        (void)kOpHeader;
        for (const auto& [id, list] : messages_) {
            if (channels_.find(id) == channels_.end()) {
                throw IoError(std::string(kKind) + " '" + path().string() +
                              "': messages of channel " + std::to_string(id) +
                              " have no channel record (corrupt file)");
            }
        }
    }

    RangedFile file_;
    std::map<std::uint16_t, std::string> schema_names_;
    std::map<std::uint16_t, Channel> channels_;
    std::map<std::uint16_t, std::vector<RecordingMessage>> messages_;
    std::uint64_t cached_chunk_pos_ = kNoChunk;
    std::string cached_chunk_;
};

}  // namespace
}  // namespace mcap_internal

std::unique_ptr<RecordingReader> open_mcap(const fs::path& path) {
    return std::make_unique<mcap_internal::McapReader>(path);
}

}  // namespace shine
