// PCD reader (ascii, binary, binary_compressed) and binary writer.
//
// binary_compressed stores, after the header, two uint32 (compressed and uncompressed size) and
// one LZF block whose decompressed bytes hold the fields one after another ("structure of
// arrays"), unlike binary which interleaves them per point.
#include "shine/io/pcd.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <string_view>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"
#include "shine/io/point_intensity.hpp"
#include "shine/io/point_times.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace pcd_internal {
namespace {

[[noreturn]] void fail(const fs::path& path, const std::string& where, const std::string& what) {
    throw IoError("PCD file '" + path.string() + "'" + (where.empty() ? "" : ", " + where) + ": " +
                  what);
}

std::vector<std::string_view> split_words(std::string_view line) {
    std::vector<std::string_view> words;
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
        const std::size_t start = i;
        while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
        if (i > start) words.push_back(line.substr(start, i - start));
    }
    return words;
}

bool parse_uint(std::string_view word, std::uint64_t* out) {
    const auto r = std::from_chars(word.data(), word.data() + word.size(), *out);
    return r.ec == std::errc() && r.ptr == word.data() + word.size() && !word.empty();
}

bool parse_double(std::string_view word, double* out) {
    const char* first = word.data();
    const char* last = word.data() + word.size();
    if (first != last && *first == '+') ++first;
    const auto r = std::from_chars(first, last, *out);
    return first != last && r.ec == std::errc() && r.ptr == last;
}

struct Field {
    std::string name;
    std::size_t size = 4;
    char type = 'F';
    std::size_t count = 1;
    std::size_t offset = 0;  // byte offset inside a binary record
};

enum class Encoding { kAscii, kBinary, kBinaryCompressed };

struct Header {
    std::vector<Field> fields;
    std::uint64_t points = 0;
    Encoding encoding = Encoding::kAscii;
    std::size_t record_size = 0;  // bytes per point in binary encodings
    std::size_t token_count = 0;  // values per point in ascii
    std::size_t data_offset = 0;
    std::size_t data_line = 0;
    int xyz_field[3] = {-1, -1, -1};
    int time_field = -1;       ///< the per-point time field (point_times.hpp), -1 without one
    int intensity_field = -1;  ///< the intensity field (point_intensity.hpp), -1 without one
};

Header parse_header(const fs::path& path, std::string_view data) {
    Header h;
    std::size_t pos = 0;
    std::size_t line_no = 0;
    bool have_sizes = false, have_types = false, have_counts = false, have_width = false;
    bool have_points = false;
    std::uint64_t width = 0, height = 1;
    std::vector<std::string_view> sizes, types, counts;
    // Header line of each keyword, for messages about its values.
    std::size_t fields_line = 0, sizes_line = 0, types_line = 0, counts_line = 0;
    std::size_t width_line = 0, points_line = 0;
    const auto line_text = [](std::size_t n) { return "line " + std::to_string(n); };
    while (true) {
        if (pos >= data.size()) {
            fail(path, "header (lines 1-" + std::to_string(line_no) + ")",
                 "ends without a DATA line");
        }
        std::size_t eol = data.find('\n', pos);
        if (eol == std::string_view::npos) eol = data.size();
        std::string_view line = data.substr(pos, eol - pos);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        pos = std::min(eol + 1, data.size());
        ++line_no;
        const std::string where = "line " + std::to_string(line_no);
        const auto words = split_words(line);
        if (words.empty() || words[0][0] == '#') continue;
        const std::string_view key = words[0];
        const auto need_args = [&](std::size_t n) {
            if (words.size() < n + 1) {
                fail(path, where,
                     printable_excerpt(key) + " needs " + std::to_string(n) + " value(s)");
            }
        };
        if (key == "VERSION" || key == "VIEWPOINT") {
            continue;
        } else if (key == "FIELDS") {
            need_args(1);
            for (std::size_t i = 1; i < words.size(); ++i) {
                h.fields.push_back(Field{std::string(words[i])});
            }
            fields_line = line_no;
        } else if (key == "SIZE") {
            need_args(1);
            sizes.assign(words.begin() + 1, words.end());
            have_sizes = true;
            sizes_line = line_no;
        } else if (key == "TYPE") {
            need_args(1);
            types.assign(words.begin() + 1, words.end());
            have_types = true;
            types_line = line_no;
        } else if (key == "COUNT") {
            need_args(1);
            counts.assign(words.begin() + 1, words.end());
            have_counts = true;
            counts_line = line_no;
        } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
            need_args(1);
            std::uint64_t value = 0;
            if (!parse_uint(words[1], &value)) {
                fail(path, where,
                     std::string(key) + " '" + printable_excerpt(words[1]) +
                         "' is not a non-negative integer below 2^64");
            }
            if (key == "WIDTH") {
                width = value;
                have_width = true;
                width_line = line_no;
            } else if (key == "HEIGHT") {
                height = value;
            } else {
                h.points = value;
                have_points = true;
                points_line = line_no;
            }
        } else if (key == "DATA") {
            need_args(1);
            if (words[1] == "ascii") {
                h.encoding = Encoding::kAscii;
            } else if (words[1] == "binary") {
                h.encoding = Encoding::kBinary;
            } else if (words[1] == "binary_compressed") {
                h.encoding = Encoding::kBinaryCompressed;
            } else {
                fail(path, where,
                     "unknown DATA encoding '" + printable_excerpt(words[1]) +
                         "' (expected ascii, binary or binary_compressed)");
            }
            break;
        } else {
            fail(path, where,
                 "unknown header keyword '" + printable_excerpt(key) + "' (not a PCD file?)");
        }
    }
    h.data_offset = pos;
    h.data_line = line_no + 1;

    const std::string header_where = "header (lines 1-" + std::to_string(line_no) + ")";
    if (h.fields.empty()) fail(path, header_where, "has no FIELDS line");
    if (!have_sizes || !have_types) fail(path, header_where, "needs SIZE and TYPE lines");
    const std::size_t nf = h.fields.size();
    if (sizes.size() != nf || types.size() != nf || (have_counts && counts.size() != nf)) {
        fail(path, "line " + std::to_string(fields_line),
             std::to_string(nf) + " FIELDS but " + std::to_string(sizes.size()) + " SIZE, " +
                 std::to_string(types.size()) + " TYPE" +
                 (have_counts ? " and " + std::to_string(counts.size()) + " COUNT" : "") +
                 " entries");
    }
    for (std::size_t i = 0; i < nf; ++i) {
        Field& f = h.fields[i];
        std::uint64_t size = 0;
        if (!parse_uint(sizes[i], &size) || (size != 1 && size != 2 && size != 4 && size != 8)) {
            fail(path, line_text(sizes_line),
                 "SIZE of field '" + printable_excerpt(f.name) + "' is '" +
                     printable_excerpt(sizes[i]) + "' (expected 1, 2, 4 or 8)");
        }
        f.size = static_cast<std::size_t>(size);
        if (types[i] != "F" && types[i] != "I" && types[i] != "U") {
            fail(path, line_text(types_line),
                 "TYPE of field '" + printable_excerpt(f.name) + "' is '" +
                     printable_excerpt(types[i]) + "' (expected F, I or U)");
        }
        f.type = types[i][0];
        if (have_counts) {
            std::uint64_t count = 0;
            // A field wider than 1e6 values per point is not a LiDAR scan; refuse it early.
            if (!parse_uint(counts[i], &count) || count == 0 || count > 1000000) {
                fail(path, line_text(counts_line),
                     "COUNT of field '" + printable_excerpt(f.name) + "' is '" +
                         printable_excerpt(counts[i]) +
                         "' (expected an integer from 1 to 1000000)");
            }
            f.count = static_cast<std::size_t>(count);
        }
        f.offset = h.record_size;
        h.record_size += f.size * f.count;
        h.token_count += f.count;
        for (int axis = 0; axis < 3; ++axis) {
            if (f.name == std::string(1, static_cast<char>('x' + axis))) {
                h.xyz_field[axis] = static_cast<int>(i);
            }
        }
    }
    for (int axis = 0; axis < 3; ++axis) {
        const std::string name(1, static_cast<char>('x' + axis));
        if (h.xyz_field[axis] < 0) {
            fail(path, "line " + std::to_string(fields_line), "has no field '" + name + "'");
        }
        const Field& f = h.fields[h.xyz_field[axis]];
        if (f.type != 'F' || (f.size != 4 && f.size != 8) || f.count != 1) {
            fail(path, line_text(fields_line),
                 "field '" + name + "' must be TYPE F, SIZE 4 or 8, COUNT 1 (found TYPE " +
                     std::string(1, f.type) + ", SIZE " + std::to_string(f.size) + ", COUNT " +
                     std::to_string(f.count) + ")");
        }
    }
    {
        std::vector<std::string> names;
        for (const Field& f : h.fields) names.push_back(f.count == 1 ? f.name : std::string());
        h.time_field = find_point_time_field(names);
        if (h.time_field >= 0) {
            const Field& f = h.fields[h.time_field];
            if (f.type == 'F' && f.size != 4 && f.size != 8) {
                fail(path, line_text(sizes_line),
                     "time field '" + f.name + "' is TYPE F with SIZE " + std::to_string(f.size) +
                         " (expected 4 or 8)");
            }
        }
    }
    {
        std::vector<std::string> names;
        for (const Field& f : h.fields) names.push_back(f.name);
        h.intensity_field = find_intensity_field(names);
        if (h.intensity_field >= 0) {
            const Field& f = h.fields[h.intensity_field];
            if (f.count != 1) {
                fail(path, line_text(counts_line),
                     "intensity field '" + f.name + "' has COUNT " + std::to_string(f.count) +
                         " (expected 1: one value per point)");
            }
            if (f.type == 'F' && f.size != 4 && f.size != 8) {
                fail(path, line_text(sizes_line),
                     "intensity field '" + f.name + "' is TYPE F with SIZE " +
                         std::to_string(f.size) + " (expected 4 or 8)");
            }
        }
    }
    if (!have_width && !have_points) fail(path, header_where, "has neither WIDTH nor POINTS");
    if (have_width) {
        if (height != 0 && width > UINT64_MAX / height) {
            fail(path, line_text(width_line), "WIDTH * HEIGHT overflows");
        }
        if (have_points && h.points != width * height) {
            fail(path, line_text(points_line),
                 "POINTS " + std::to_string(h.points) +
                     " differs from WIDTH * HEIGHT = " + std::to_string(width * height));
        }
        h.points = width * height;
    }
    return h;
}

/// Reads one coordinate (F4 or F8, little-endian as every PCD writer in practice produces).
float read_coordinate(const char* p, std::size_t size) {
    if (size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
    }
    double v;
    std::memcpy(&v, p, 8);
    return static_cast<float>(v);
}

/// Reads one value of any PCD type (little-endian) as a double.
double read_value(const char* p, const Field& f) {
    const auto load = [p](auto v) {
        std::memcpy(&v, p, sizeof(v));
        return static_cast<double>(v);
    };
    if (f.type == 'F') return f.size == 4 ? load(float{}) : load(double{});
    if (f.type == 'I') {
        switch (f.size) {
            case 1:
                return load(std::int8_t{});
            case 2:
                return load(std::int16_t{});
            case 4:
                return load(std::int32_t{});
            default:
                return load(std::int64_t{});
        }
    }
    switch (f.size) {
        case 1:
            return load(std::uint8_t{});
        case 2:
            return load(std::uint16_t{});
        case 4:
            return load(std::uint32_t{});
        default:
            return load(std::uint64_t{});
    }
}

std::vector<Eigen::Vector3f> read_ascii(const fs::path& path, std::string_view data,
                                        const Header& h, std::vector<double>* times,
                                        std::vector<float>* intensity) {
    const std::size_t remaining = data.size() - h.data_offset;
    // Each point needs at least one character and one separator per value.
    if (h.points > (remaining + 1) / (2 * h.token_count)) {
        fail(path, "line " + std::to_string(h.data_line),
             "header declares " + std::to_string(h.points) + " points but only " +
                 std::to_string(remaining) +
                 " bytes of data follow: truncated file or corrupt "
                 "header");
    }
    // Token index of x, y, z (and the time) within a line.
    const auto token_of = [&h](int field) {
        std::size_t t = 0;
        for (int i = 0; i < field; ++i) t += h.fields[i].count;
        return t;
    };
    std::size_t xyz_token[3];
    for (int axis = 0; axis < 3; ++axis) xyz_token[axis] = token_of(h.xyz_field[axis]);
    const std::size_t time_token = h.time_field >= 0 ? token_of(h.time_field) : 0;
    if (h.time_field >= 0) times->reserve(static_cast<std::size_t>(h.points));
    const std::size_t intensity_token = h.intensity_field >= 0 ? token_of(h.intensity_field) : 0;
    if (h.intensity_field >= 0) intensity->reserve(static_cast<std::size_t>(h.points));
    std::vector<Eigen::Vector3f> points;
    points.reserve(static_cast<std::size_t>(h.points));
    std::size_t pos = h.data_offset;
    std::size_t line_no = h.data_line - 1;
    while (pos < data.size()) {
        std::size_t eol = data.find('\n', pos);
        if (eol == std::string_view::npos) eol = data.size();
        const std::string_view line = data.substr(pos, eol - pos);
        pos = eol + 1;
        ++line_no;
        const auto words = split_words(line);
        if (words.empty()) continue;
        const std::string where = "line " + std::to_string(line_no);
        if (points.size() == h.points) {
            fail(path, where,
                 "more data lines than the " + std::to_string(h.points) +
                     " points the header declares");
        }
        if (words.size() != h.token_count) {
            fail(path, where,
                 "expected " + std::to_string(h.token_count) + " values, found " +
                     std::to_string(words.size()));
        }
        Eigen::Vector3f p;
        for (int axis = 0; axis < 3; ++axis) {
            double v = 0.0;
            if (!parse_double(words[xyz_token[axis]], &v)) {
                fail(path, where,
                     "'" + printable_excerpt(words[xyz_token[axis]]) + "' is not a number");
            }
            p[axis] = static_cast<float>(v);
        }
        if (h.time_field >= 0) {
            double t = 0.0;
            if (!parse_double(words[time_token], &t)) {
                fail(path, where,
                     "time '" + printable_excerpt(words[time_token]) + "' is not a number");
            }
            times->push_back(t);
        }
        if (h.intensity_field >= 0) {
            double value = 0.0;
            if (!parse_double(words[intensity_token], &value)) {
                fail(path, where,
                     "intensity '" + printable_excerpt(words[intensity_token]) +
                         "' is not a number");
            }
            intensity->push_back(static_cast<float>(value));
        }
        points.push_back(p);
    }
    if (points.size() != h.points) {
        fail(path, "line " + std::to_string(line_no),
             "file is truncated: " + std::to_string(points.size()) + " of " +
                 std::to_string(h.points) + " points present");
    }
    return points;
}

std::vector<Eigen::Vector3f> read_binary(const fs::path& path, std::string_view data,
                                         const Header& h, std::vector<double>* times,
                                         std::vector<float>* intensity) {
    const std::size_t remaining = data.size() - h.data_offset;
    if (h.points > remaining / h.record_size) {
        fail(path, "byte offset " + std::to_string(h.data_offset),
             "header declares " + std::to_string(h.points) + " points of " +
                 std::to_string(h.record_size) + " bytes but only " + std::to_string(remaining) +
                 " bytes of data follow: truncated file or corrupt header");
    }
    std::vector<Eigen::Vector3f> points(static_cast<std::size_t>(h.points));
    const char* base = data.data() + h.data_offset;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const char* record = base + i * h.record_size;
        for (int axis = 0; axis < 3; ++axis) {
            const Field& f = h.fields[h.xyz_field[axis]];
            points[i][axis] = read_coordinate(record + f.offset, f.size);
        }
    }
    if (h.time_field >= 0) {
        const Field& f = h.fields[h.time_field];
        times->resize(points.size());
        for (std::size_t i = 0; i < points.size(); ++i) {
            (*times)[i] = read_value(base + i * h.record_size + f.offset, f);
        }
    }
    if (h.intensity_field >= 0) {
        const Field& f = h.fields[h.intensity_field];
        intensity->resize(points.size());
        for (std::size_t i = 0; i < points.size(); ++i) {
            (*intensity)[i] =
                static_cast<float>(read_value(base + i * h.record_size + f.offset, f));
        }
    }
    return points;
}

std::uint32_t load_u32_le(const char* p) {
    const auto* b = reinterpret_cast<const unsigned char*>(p);
    return static_cast<std::uint32_t>(b[0]) | (static_cast<std::uint32_t>(b[1]) << 8) |
           (static_cast<std::uint32_t>(b[2]) << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}

/// Decompresses one LZF block (liblzf's format) into exactly out_size bytes, bounds-checked.
void lzf_decompress(const unsigned char* in, std::size_t in_size, unsigned char* out,
                    std::size_t out_size, const fs::path& path, std::size_t file_offset) {
    std::size_t ip = 0;
    std::size_t op = 0;
    const auto corrupt = [&](const std::string& what) {
        fail(path, "byte offset " + std::to_string(file_offset + ip), "corrupt LZF block: " + what);
    };
    while (ip < in_size) {
        const unsigned ctrl = in[ip++];
        if (ctrl < 32) {
            // Literal run of ctrl + 1 bytes.
            const std::size_t len = ctrl + 1;
            if (len > in_size - ip) corrupt("literal run past the end of the block");
            if (len > out_size - op) corrupt("output longer than the declared size");
            std::memcpy(out + op, in + ip, len);
            ip += len;
            op += len;
        } else {
            // Back-reference: length in the top 3 bits (7 = extended by one byte), distance in
            // the low 5 bits plus the next byte.
            std::size_t len = ctrl >> 5;
            if (len == 7) {
                if (ip >= in_size) corrupt("back-reference length past the end of the block");
                len += in[ip++];
            }
            len += 2;
            if (ip >= in_size) corrupt("back-reference distance past the end of the block");
            const std::size_t distance = ((ctrl & 0x1fu) << 8) + in[ip++] + 1;
            if (distance > op) corrupt("back-reference before the start of the output");
            if (len > out_size - op) corrupt("output longer than the declared size");
            // Byte by byte: the source may overlap the destination (run-length encoding).
            for (std::size_t k = 0; k < len; ++k, ++op) out[op] = out[op - distance];
        }
    }
    if (op != out_size) {
        corrupt("decompressed " + std::to_string(op) + " bytes, header declares " +
                std::to_string(out_size));
    }
}

std::vector<Eigen::Vector3f> read_compressed(const fs::path& path, std::string_view data,
                                             const Header& h, std::vector<double>* times,
                                             std::vector<float>* intensity) {
    const std::size_t remaining = data.size() - h.data_offset;
    const std::string sizes_where = "byte offset " + std::to_string(h.data_offset);
    if (remaining < 8) {
        fail(path, sizes_where, "file is truncated: the compressed block sizes are missing");
    }
    const std::size_t compressed = load_u32_le(data.data() + h.data_offset);
    const std::size_t uncompressed = load_u32_le(data.data() + h.data_offset + 4);
    if (compressed > remaining - 8) {
        fail(path, sizes_where,
             "compressed block of " + std::to_string(compressed) + " bytes declared but only " +
                 std::to_string(remaining - 8) + " bytes follow: truncated file");
    }
    if (h.points == 0) return {};
    if (h.points > uncompressed / h.record_size || h.points * h.record_size != uncompressed) {
        fail(path, sizes_where,
             "uncompressed size " + std::to_string(uncompressed) + " does not match " +
                 std::to_string(h.points) + " points of " + std::to_string(h.record_size) +
                 " bytes");
    }
    // An LZF back-reference of 3 bytes expands to at most 264 bytes, so no valid block grows by
    // more than a factor 88: check before allocating what the header asks for.
    constexpr std::size_t kMaxLzfExpansion = 88;
    if (uncompressed / kMaxLzfExpansion > compressed) {
        fail(path, sizes_where,
             "uncompressed size " + std::to_string(uncompressed) + " is impossible for a " +
                 std::to_string(compressed) + "-byte LZF block: corrupt header");
    }
    std::string soa(uncompressed, '\0');
    const std::size_t block_offset = h.data_offset + 8;
    lzf_decompress(reinterpret_cast<const unsigned char*>(data.data() + block_offset), compressed,
                   reinterpret_cast<unsigned char*>(soa.data()), uncompressed, path, block_offset);
    const std::size_t n = static_cast<std::size_t>(h.points);
    std::vector<Eigen::Vector3f> points(n);
    for (int axis = 0; axis < 3; ++axis) {
        const Field& f = h.fields[h.xyz_field[axis]];
        // Field-major: field k starts after all points' values of fields 0..k-1.
        const char* column = soa.data() + f.offset * n;
        for (std::size_t i = 0; i < n; ++i) {
            points[i][axis] = read_coordinate(column + i * f.size, f.size);
        }
    }
    if (h.time_field >= 0) {
        const Field& f = h.fields[h.time_field];
        const char* column = soa.data() + f.offset * n;
        times->resize(n);
        for (std::size_t i = 0; i < n; ++i) (*times)[i] = read_value(column + i * f.size, f);
    }
    if (h.intensity_field >= 0) {
        const Field& f = h.fields[h.intensity_field];
        const char* column = soa.data() + f.offset * n;
        intensity->resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            (*intensity)[i] = static_cast<float>(read_value(column + i * f.size, f));
        }
    }
    return points;
}

}  // namespace
}  // namespace pcd_internal

std::vector<Eigen::Vector3f> read_pcd_points(const fs::path& path) {
    return parse_pcd_points(read_file_contents(path, "PCD file", "a .pcd file"), path);
}

std::vector<Eigen::Vector3f> parse_pcd_points(std::string_view data, const fs::path& path) {
    return parse_pcd_scan(data, path).points_sensor;
}

TimedPoints read_pcd_scan(const fs::path& path, std::optional<double> stamp_s) {
    return parse_pcd_scan(read_file_contents(path, "PCD file", "a .pcd file"), path, stamp_s);
}

TimedPoints parse_pcd_scan(std::string_view data, const fs::path& path,
                           std::optional<double> stamp_s) {
    using namespace pcd_internal;
    const Header header = parse_header(path, data);
    TimedPoints scan;
    std::vector<double> raw_times;
    switch (header.encoding) {
        case Encoding::kAscii:
            scan.points_sensor = read_ascii(path, data, header, &raw_times, &scan.intensity);
            break;
        case Encoding::kBinary:
            scan.points_sensor = read_binary(path, data, header, &raw_times, &scan.intensity);
            break;
        case Encoding::kBinaryCompressed:
            scan.points_sensor = read_compressed(path, data, header, &raw_times, &scan.intensity);
            break;
    }
    if (header.time_field >= 0) {
        const Field& f = header.fields[header.time_field];
        scan.time_format.field = f.name;
        scan.time_format.type = std::string(1, f.type) + std::to_string(f.size);
        scan.point_time_s =
            point_times_relative_s(raw_times, f.type != 'F', stamp_s, &scan.time_format);
    }
    drop_unmeasured_intensity(scan.intensity);
    if (!scan.intensity.empty()) scan.intensity_field = header.fields[header.intensity_field].name;
    return scan;
}

void write_pcd_points(const fs::path& path, const std::vector<Eigen::Vector3f>& points) {
    const std::string n = std::to_string(points.size());
    const std::string header =
        "# .PCD v0.7 - Point Cloud Data file format (written by ShineVDB)\n"
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " +
        n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA binary\n";
    std::string buffer(header.size() + points.size() * 12, '\0');
    std::memcpy(buffer.data(), header.data(), header.size());
    char* out = buffer.data() + header.size();
    for (const auto& p : points) {
        std::memcpy(out, p.data(), 12);  // Eigen::Vector3f stores x y z contiguously
        out += 12;
    }
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    });
}

}  // namespace shine
