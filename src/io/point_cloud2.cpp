// sensor_msgs/PointCloud2 decoding (ROS 1 serialisation and CDR) and a small encoder for tests.
//
// ROS 1 serialisation: little-endian, no alignment, strings and arrays u32 length + elements.
// CDR (OMG CDR as ROS 2's rmw writes it): a 4-byte encapsulation header (0x00 0x01 = little
// endian), then each primitive aligned to its size relative to the end of that header; strings
// are u32 length (including the terminating NUL) + bytes.
#include "shine/io/point_cloud2.hpp"

#include <cmath>
#include <cstring>

#include "recording_bytes.hpp"
#include "shine/core/error.hpp"
#include "shine/io/point_intensity.hpp"
#include "shine/io/point_times.hpp"

namespace shine {

namespace point_cloud2_internal {
namespace {

using recording_internal::ByteCursor;

// sensor_msgs/PointField datatypes.
constexpr std::uint8_t kInt8 = 1, kUint8 = 2, kInt16 = 3, kUint16 = 4, kInt32 = 5, kUint32 = 6,
                       kFloat32 = 7, kFloat64 = 8;

std::size_t datatype_bytes(std::uint8_t type) {
    switch (type) {
        case kInt8:
        case kUint8:
            return 1;
        case kInt16:
        case kUint16:
            return 2;
        case kInt32:
        case kUint32:
        case kFloat32:
            return 4;
        case kFloat64:
            return 8;
        default:
            return 0;
    }
}

struct Field {
    std::string name;
    std::uint32_t offset = 0;
    std::uint8_t datatype = 0;
    std::uint32_t count = 0;
};

struct Cloud {
    double stamp_s = 0.0;
    std::string frame_id;
    std::uint32_t height = 0, width = 0;
    std::vector<Field> fields;
    bool big_endian = false;
    std::uint32_t point_step = 0, row_step = 0;
    std::string_view data;
};

/// Reads primitives with or without CDR alignment.
class Reader {
  public:
    Reader(std::string_view bytes, const std::filesystem::path& source, bool cdr)
        : c_(bytes, source, "PointCloud2", 0), cdr_(cdr) {}
    std::uint8_t u8(const char* what) { return c_.u8(what); }
    std::uint32_t u32(const char* what) {
        if (cdr_) c_.align(4);
        return c_.u32(what);
    }
    std::string str(const char* what) {
        const std::uint32_t n = u32(what);
        std::string_view s = c_.bytes(n, what);
        if (cdr_) {
            if (n == 0 || s.back() != '\0') c_.fail(std::string(what) + " lacks its NUL");
            s.remove_suffix(1);
        }
        return std::string(s);
    }
    std::string_view bytes(const char* what) {
        const std::uint32_t n = u32(what);
        return c_.bytes(n, what);
    }
    ByteCursor& cursor() { return c_; }

  private:
    ByteCursor c_;
    bool cdr_;
};

Cloud parse(std::string_view message, MessageEncoding encoding, const std::string& where) {
    const bool cdr = encoding == MessageEncoding::kCdr;
    const std::filesystem::path source = where;
    if (cdr) {
        if (message.size() < 4) {
            throw IoError(where + ": truncated PointCloud2 (" + std::to_string(message.size()) +
                          " bytes, less than the CDR header)");
        }
        const auto b0 = static_cast<std::uint8_t>(message[0]);
        const auto b1 = static_cast<std::uint8_t>(message[1]);
        if (b0 == 0x00 && b1 == 0x00) {
            throw IoError(where +
                          ": the message is big-endian CDR, which is not supported: re-record "
                          "on a little-endian machine or convert the bag");
        }
        if (b0 != 0x00 || b1 != 0x01) {
            throw IoError(where + ": unknown CDR encapsulation " + std::to_string(b0) + "," +
                          std::to_string(b1) + " (expected 0,1: little-endian plain CDR)");
        }
        message.remove_prefix(4);
    }
    Reader r(message, source, cdr);
    Cloud cloud;
    if (!cdr) r.u32("header.seq");
    const std::uint32_t sec = r.u32("header.stamp.sec");
    const std::uint32_t nsec = r.u32("header.stamp.nanosec");
    // ROS 2 stamps are int32 seconds, ROS 1 uint32; negative stamps do not occur in recordings.
    cloud.stamp_s =
        (cdr ? static_cast<double>(static_cast<std::int32_t>(sec)) : static_cast<double>(sec)) +
        static_cast<double>(nsec) * 1e-9;
    cloud.frame_id = r.str("header.frame_id");
    cloud.height = r.u32("height");
    cloud.width = r.u32("width");
    const std::uint32_t n_fields = r.u32("fields length");
    if (n_fields > message.size())
        r.cursor().fail("field count " + std::to_string(n_fields) + " is larger than the message");
    for (std::uint32_t i = 0; i < n_fields; ++i) {
        Field f;
        f.name = r.str("field name");
        f.offset = r.u32("field offset");
        f.datatype = r.u8("field datatype");
        f.count = r.u32("field count");
        cloud.fields.push_back(std::move(f));
    }
    cloud.big_endian = r.u8("is_bigendian") != 0;
    cloud.point_step = r.u32("point_step");
    cloud.row_step = r.u32("row_step");
    cloud.data = r.bytes("data");
    r.u8("is_dense");
    return cloud;
}

const Field* find_field(const Cloud& cloud, const char* name) {
    for (const Field& f : cloud.fields) {
        if (f.name == name) return &f;
    }
    return nullptr;
}

std::string field_list(const Cloud& cloud) {
    std::string s;
    for (const Field& f : cloud.fields) s += (s.empty() ? "" : " ") + f.name;
    return s.empty() ? "none" : s;
}

template <class T>
T load(const char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

double read_number(const char* p, std::uint8_t type) {
    switch (type) {
        case kInt8:
            return load<std::int8_t>(p);
        case kUint8:
            return load<std::uint8_t>(p);
        case kInt16:
            return load<std::int16_t>(p);
        case kUint16:
            return load<std::uint16_t>(p);
        case kInt32:
            return load<std::int32_t>(p);
        case kUint32:
            return load<std::uint32_t>(p);
        case kFloat32:
            return static_cast<double>(load<float>(p));
        default:
            return load<double>(p);
    }
}

}  // namespace
}  // namespace point_cloud2_internal

PointCloud2Scan decode_point_cloud2(std::string_view message, MessageEncoding encoding,
                                    const std::string& where) {
    using namespace point_cloud2_internal;
    const Cloud cloud = parse(message, encoding, where);
    PointCloud2Scan out;
    out.stamp_s = cloud.stamp_s;
    out.frame_id = cloud.frame_id;
    if (cloud.big_endian) {
        throw IoError(where +
                      ": the PointCloud2 is big-endian (is_bigendian = true), which is not "
                      "supported: convert the cloud to little-endian before recording");
    }
    const Field* axes[3] = {find_field(cloud, "x"), find_field(cloud, "y"), find_field(cloud, "z")};
    for (const Field* f : axes) {
        if (!f || (f->datatype != kFloat32 && f->datatype != kFloat64) || f->count < 1) {
            throw DataError(where +
                            ": the PointCloud2 needs fields x, y and z as float32 or "
                            "float64; its fields: " +
                            field_list(cloud));
        }
    }
    const Field* time = nullptr;
    for (const std::string_view name : point_time_field_names()) {
        time = find_field(cloud, std::string(name).c_str());
        if (time) break;
    }
    if (time) {
        const std::uint8_t tt = time->datatype;
        if (tt < kInt8 || tt > kFloat64) {
            throw DataError(where + ": per-point time field '" + time->name + "' has datatype " +
                            std::to_string(tt) +
                            "; supported are the integer types (nanoseconds) and float32/float64 "
                            "(seconds)");
        }
    }
    const Field* intensity = nullptr;
    {
        std::vector<std::string> names;
        for (const Field& f : cloud.fields) names.push_back(f.name);
        const int index = find_intensity_field(names);
        if (index >= 0) intensity = &cloud.fields[static_cast<std::size_t>(index)];
    }
    if (intensity) {
        if (datatype_bytes(intensity->datatype) == 0) {
            throw DataError(where + ": intensity field '" + intensity->name + "' has datatype " +
                            std::to_string(intensity->datatype) +
                            "; supported are sensor_msgs/PointField's 1 (int8) to 8 (float64)");
        }
        if (intensity->count != 1) {
            throw DataError(where + ": intensity field '" + intensity->name + "' has count " +
                            std::to_string(intensity->count) +
                            "; expected 1 (one value per point)");
        }
    }
    const std::uint64_t n_points = std::uint64_t{cloud.width} * cloud.height;
    if (n_points == 0) return out;
    // Every field used must lie inside a point; every point inside the data.
    const auto check_field = [&](const Field& f, std::size_t bytes) {
        if (std::uint64_t{f.offset} + bytes > cloud.point_step) {
            throw IoError(where + ": field '" + f.name + "' (offset " + std::to_string(f.offset) +
                          ", " + std::to_string(bytes) + " bytes) does not fit in point_step " +
                          std::to_string(cloud.point_step) + " (corrupt message)");
        }
    };
    for (const Field* f : axes) check_field(*f, datatype_bytes(f->datatype));
    if (time) check_field(*time, datatype_bytes(time->datatype));
    if (intensity) check_field(*intensity, datatype_bytes(intensity->datatype));
    if (std::uint64_t{cloud.width} * cloud.point_step > cloud.row_step) {
        throw IoError(where + ": row_step " + std::to_string(cloud.row_step) +
                      " is smaller than width " + std::to_string(cloud.width) + " x point_step " +
                      std::to_string(cloud.point_step) + " (corrupt message)");
    }
    const std::uint64_t needed = std::uint64_t{cloud.row_step} * (cloud.height - 1) +
                                 std::uint64_t{cloud.width} * cloud.point_step;
    if (needed > cloud.data.size()) {
        throw IoError(where + ": data holds " + std::to_string(cloud.data.size()) + " bytes, " +
                      std::to_string(cloud.height) + " rows of " + std::to_string(cloud.width) +
                      " points need " + std::to_string(needed) + " (truncated message)");
    }
    out.points_sensor.reserve(static_cast<std::size_t>(n_points));
    std::vector<double> raw_time;
    if (time) raw_time.reserve(static_cast<std::size_t>(n_points));
    if (intensity) out.intensity.reserve(static_cast<std::size_t>(n_points));
    for (std::uint32_t row = 0; row < cloud.height; ++row) {
        const char* row_data = cloud.data.data() + std::size_t{row} * cloud.row_step;
        for (std::uint32_t col = 0; col < cloud.width; ++col) {
            const char* p = row_data + std::size_t{col} * cloud.point_step;
            Eigen::Vector3f v;
            for (int a = 0; a < 3; ++a) {
                const char* q = p + axes[a]->offset;
                v[a] = axes[a]->datatype == kFloat32 ? load<float>(q)
                                                     : static_cast<float>(load<double>(q));
            }
            out.points_sensor.push_back(v);
            if (time) {
                raw_time.push_back(read_number(p + time->offset, time->datatype));
            }
            if (intensity) {
                out.intensity.push_back(
                    static_cast<float>(read_number(p + intensity->offset, intensity->datatype)));
            }
        }
    }
    if (time) {
        // Unit and reference by point_times.hpp's rules; absolute times lose the header stamp.
        const bool integer = time->datatype != kFloat32 && time->datatype != kFloat64;
        static const char* const kTypeNames[] = {"",      "int8",   "uint8",   "int16",  "uint16",
                                                 "int32", "uint32", "float32", "float64"};
        out.time_format.field = time->name;
        out.time_format.type = kTypeNames[time->datatype];
        out.point_time_s = point_times_relative_s(raw_time, integer, out.stamp_s, &out.time_format);
        out.time_field = time->name;
    }
    drop_unmeasured_intensity(out.intensity);
    if (!out.intensity.empty()) out.intensity_field = intensity->name;
    return out;
}

double decode_header_stamp_s(std::string_view message, MessageEncoding encoding,
                             const std::string& where) {
    const bool cdr = encoding == MessageEncoding::kCdr;
    // CDR: encapsulation header, sec, nsec; ROS 1: seq, sec, nsec.
    if (message.size() < 12) {
        throw IoError(where + ": truncated message (" + std::to_string(message.size()) +
                      " bytes, too short for a header stamp)");
    }
    std::uint32_t sec, nsec;
    std::memcpy(&sec, message.data() + 4, 4);
    std::memcpy(&nsec, message.data() + 8, 4);
    if (cdr && (message[0] != 0 || message[1] != 1)) {
        // decode_point_cloud2 gives the precise message (big-endian, unknown encapsulation).
        return decode_point_cloud2(message, encoding, where).stamp_s;
    }
    return (cdr ? static_cast<double>(static_cast<std::int32_t>(sec)) : static_cast<double>(sec)) +
           static_cast<double>(nsec) * 1e-9;
}

namespace point_cloud2_internal {
namespace {

/// Writes primitives with or without CDR alignment.
class Writer {
  public:
    explicit Writer(bool cdr) : cdr_(cdr) {}
    void u8(std::uint8_t v) { out_.push_back(static_cast<char>(v)); }
    void u32(std::uint32_t v) {
        if (cdr_) {
            while (out_.size() % 4 != 0) out_.push_back('\0');
        }
        out_.append(reinterpret_cast<const char*>(&v), 4);
    }
    void str(const std::string& s) {
        u32(static_cast<std::uint32_t>(s.size() + (cdr_ ? 1 : 0)));
        out_ += s;
        if (cdr_) out_.push_back('\0');
    }
    void bytes(const std::string& b) {
        u32(static_cast<std::uint32_t>(b.size()));
        out_ += b;
    }
    std::string& out() { return out_; }

  private:
    bool cdr_;
    std::string out_;
};

}  // namespace
}  // namespace point_cloud2_internal

std::string encode_point_cloud2(const PointCloud2Scan& scan, MessageEncoding encoding) {
    using namespace point_cloud2_internal;
    const bool cdr = encoding == MessageEncoding::kCdr;
    const bool with_time = !scan.point_time_s.empty();
    const bool with_intensity = !scan.intensity.empty();
    if ((with_time && scan.point_time_s.size() != scan.points_sensor.size()) ||
        (with_intensity && scan.intensity.size() != scan.points_sensor.size())) {
        throw DataError("encode_point_cloud2: " + std::to_string(scan.points_sensor.size()) +
                        " points, " + std::to_string(scan.point_time_s.size()) + " times and " +
                        std::to_string(scan.intensity.size()) +
                        " intensities (each must be one per point, or none)");
    }
    Writer w(cdr);
    if (!cdr) w.u32(0);  // seq
    const double sec = std::floor(scan.stamp_s);
    w.u32(static_cast<std::uint32_t>(static_cast<std::int64_t>(sec)));
    w.u32(static_cast<std::uint32_t>(std::llround((scan.stamp_s - sec) * 1e9)));
    w.str(scan.frame_id);
    w.u32(1);  // height
    w.u32(static_cast<std::uint32_t>(scan.points_sensor.size()));
    const std::uint32_t point_step = with_time ? 24 : 16;
    std::vector<Field> fields = {{"x", 0, kFloat32, 1},
                                 {"y", 4, kFloat32, 1},
                                 {"z", 8, kFloat32, 1},
                                 {"intensity", 12, kFloat32, 1}};
    if (with_time) fields.push_back({"t", 16, kFloat64, 1});
    w.u32(static_cast<std::uint32_t>(fields.size()));
    for (const Field& f : fields) {
        w.str(f.name);
        w.u32(f.offset);
        w.u8(f.datatype);
        w.u32(f.count);
    }
    w.u8(0);  // is_bigendian
    w.u32(point_step);
    w.u32(point_step * static_cast<std::uint32_t>(scan.points_sensor.size()));
    std::string data(scan.points_sensor.size() * point_step, '\0');
    for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
        std::memcpy(&data[i * point_step], scan.points_sensor[i].data(), 12);
        if (with_intensity) std::memcpy(&data[i * point_step + 12], &scan.intensity[i], 4);
        if (with_time) std::memcpy(&data[i * point_step + 16], &scan.point_time_s[i], 8);
    }
    w.bytes(data);
    w.u8(1);  // is_dense
    std::string out = w.out();
    if (cdr) out.insert(0, std::string("\x00\x01\x00\x00", 4));
    return out;
}

}  // namespace shine
