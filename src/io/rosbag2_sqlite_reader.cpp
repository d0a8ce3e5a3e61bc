// rosbag2 SQLite reader: the `topics` and `messages` tables that rosbag2's sqlite3 storage plugin
// creates, read with libsqlite3 in read-only, immutable mode.
#include "shine/io/rosbag2_sqlite_reader.hpp"

#include <sqlite3.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>

#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace rosbag2_sqlite_internal {
namespace {

constexpr const char* kKind = "ROS 2 SQLite bag";

class Statement {
  public:
    Statement(sqlite3* db, const char* sql, const fs::path& path) : db_(db), path_(path) {
        if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) fail("query");
    }
    ~Statement() { sqlite3_finalize(stmt_); }
    Statement(const Statement&) = delete;
    Statement& operator=(const Statement&) = delete;
    /// Advances to the next row; false at the end.
    bool step() {
        const int rc = sqlite3_step(stmt_);
        if (rc == SQLITE_ROW) return true;
        if (rc == SQLITE_DONE) return false;
        fail("read");
    }
    void reset() { sqlite3_reset(stmt_); }
    sqlite3_stmt* get() { return stmt_; }
    std::string text(int col) {
        const unsigned char* t = sqlite3_column_text(stmt_, col);
        return t ? reinterpret_cast<const char*>(t) : "";
    }
    [[noreturn]] void fail(const char* what) const {
        throw IoError(std::string(kKind) + " '" + path_.string() + "': " + what +
                      " failed: " + sqlite3_errmsg(db_) +
                      " (is it a rosbag2 .db3 file with tables topics and messages?)");
    }

  private:
    sqlite3* db_;
    const fs::path& path_;
    sqlite3_stmt* stmt_ = nullptr;
};

struct Topic {
    std::string name;
    std::string type;
    std::string serialization_format;
};

class Rosbag2SqliteReader final : public RecordingReader {
  public:
    explicit Rosbag2SqliteReader(const fs::path& path) : RecordingReader(path) {
        std::error_code ec;
        if (!fs::is_regular_file(path, ec)) {
            throw IoError(std::string(kKind) + " '" + path.string() +
                          "' does not exist or is not a file");
        }
        if (fs::file_size(path, ec) == 0) {
            throw IoError(std::string(kKind) + " '" + path.string() +
                          "' is empty (was the recording stopped before it wrote anything?)");
        }
        {
            std::ifstream in(path, std::ios::binary);
            char magic[16] = {};
            in.read(magic, 16);
            if (!in || std::string(magic, 16) != std::string("SQLite format 3\0", 16)) {
                throw IoError("'" + path.string() +
                              "' is not a ROS 2 SQLite bag: it does not start with the SQLite "
                              "header \"SQLite format 3\"");
            }
        }
        // immutable=1: no locks, no journal, the file is never written.
        const std::string uri =
            "file:" + uri_escape(fs::absolute(path).string()) + "?mode=ro&immutable=1";
        const int rc =
            sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
        if (rc != SQLITE_OK) {
            const std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
            sqlite3_close(db_);
            db_ = nullptr;
            throw IoError(std::string(kKind) + " '" + path.string() + "': cannot open: " + msg);
        }
        try {
            index();
        } catch (...) {
            sqlite3_close(db_);
            db_ = nullptr;
            throw;
        }
    }
    ~Rosbag2SqliteReader() override {
        prefix_.reset();
        read_.reset();  // statements are finalised before the connection closes
        sqlite3_close(db_);
    }

    std::string kind() const override { return kKind; }

    std::vector<RecordingTopic> topics() const override {
        std::map<std::string, RecordingTopic> by_name;
        for (const auto& [id, topic] : topics_) {
            RecordingTopic& t = by_name[topic.name];
            t.name = topic.name;
            t.type = topic.type;
            t.encoding = topic.serialization_format == "ros1" ? MessageEncoding::kRos1
                                                              : MessageEncoding::kCdr;
            const auto it = counts_.find(id);
            if (it != counts_.end()) t.message_count += it->second;
        }
        std::vector<RecordingTopic> out;
        for (auto& [name, t] : by_name) out.push_back(t);
        return out;
    }

    std::vector<RecordingMessage> messages(const std::string& topic) const override {
        std::vector<RecordingMessage> out;
        Statement q(db_,
                    "SELECT messages.id, messages.timestamp FROM messages JOIN topics ON "
                    "messages.topic_id = topics.id WHERE topics.name = ?1 ORDER BY "
                    "messages.timestamp, messages.id",
                    path());
        sqlite3_bind_text(q.get(), 1, topic.c_str(), -1, SQLITE_TRANSIENT);
        while (q.step()) {
            RecordingMessage m;
            m.offset = static_cast<std::uint64_t>(sqlite3_column_int64(q.get(), 0));
            m.log_time_ns = sqlite3_column_int64(q.get(), 1);
            out.push_back(m);
        }
        return out;
    }

    std::string read(const RecordingMessage& m) override {
        if (!read_) {
            read_ =
                std::make_unique<Statement>(db_, "SELECT data FROM messages WHERE id = ?1", path());
        }
        read_->reset();
        sqlite3_bind_int64(read_->get(), 1, static_cast<sqlite3_int64>(m.offset));
        if (!read_->step()) {
            throw IoError(std::string(kKind) + " '" + path().string() + "': message row " +
                          std::to_string(m.offset) + " is gone (was the file changed?)");
        }
        const void* blob = sqlite3_column_blob(read_->get(), 0);
        const int bytes = sqlite3_column_bytes(read_->get(), 0);
        std::string out(static_cast<std::size_t>(bytes), '\0');
        if (bytes > 0) std::memcpy(out.data(), blob, static_cast<std::size_t>(bytes));
        read_->reset();
        return out;
    }

    std::string read_prefix(const RecordingMessage& m, std::size_t bytes) override {
        if (!prefix_) {
            prefix_ = std::make_unique<Statement>(
                db_, "SELECT substr(data, 1, ?2) FROM messages WHERE id = ?1", path());
        }
        prefix_->reset();
        sqlite3_bind_int64(prefix_->get(), 1, static_cast<sqlite3_int64>(m.offset));
        sqlite3_bind_int64(prefix_->get(), 2, static_cast<sqlite3_int64>(bytes));
        if (!prefix_->step()) {
            throw IoError(std::string(kKind) + " '" + path().string() + "': message row " +
                          std::to_string(m.offset) + " is gone (was the file changed?)");
        }
        const void* blob = sqlite3_column_blob(prefix_->get(), 0);
        const int n = sqlite3_column_bytes(prefix_->get(), 0);
        std::string out(static_cast<std::size_t>(n), '\0');
        if (n > 0) std::memcpy(out.data(), blob, static_cast<std::size_t>(n));
        prefix_->reset();
        return out;
    }

  private:
    static std::string uri_escape(const std::string& s) {
        std::string out;
        for (char c : s) {
            if (c == '%' || c == '?' || c == '#') {
                char buf[4];
                std::snprintf(buf, sizeof(buf), "%%%02X", static_cast<unsigned char>(c));
                out += buf;
            } else {
                out += c;
            }
        }
        return out;
    }

    void index() {
        {
            Statement q(db_, "SELECT id, name, type, serialization_format FROM topics", path());
            while (q.step()) {
                topics_[sqlite3_column_int64(q.get(), 0)] = {q.text(1), q.text(2), q.text(3)};
            }
        }
        Statement q(db_, "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id", path());
        while (q.step()) {
            counts_[sqlite3_column_int64(q.get(), 0)] =
                static_cast<std::size_t>(sqlite3_column_int64(q.get(), 1));
        }
    }

    sqlite3* db_ = nullptr;
    std::map<std::int64_t, Topic> topics_;
    std::map<std::int64_t, std::size_t> counts_;
    std::unique_ptr<Statement> read_;
    std::unique_ptr<Statement> prefix_;
};

}  // namespace
}  // namespace rosbag2_sqlite_internal

std::unique_ptr<RecordingReader> open_rosbag2_sqlite(const fs::path& path) {
    return std::make_unique<rosbag2_sqlite_internal::Rosbag2SqliteReader>(path);
}

}  // namespace shine
