// PLY reader and writer.
//
// The reader loads the whole file into memory once, parses the header, checks every element count
// against the bytes that actually follow the header (so a corrupt header cannot make us allocate
// gigabytes), then walks the body with a bounds-checked cursor (binary) or tokenizer (ascii).
// The writer fills one contiguous buffer and hands it to the stream in a single call; the stream
// writer (meshes too large to hold) spools vertices and faces to two files and joins them.
#include "shine/io/ply.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <string_view>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"
#include "shine/io/point_intensity.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace ply_internal {
namespace {

[[noreturn]] void fail(const fs::path& path, const std::string& where, const std::string& what) {
    throw IoError("PLY file '" + path.string() + "'" + (where.empty() ? "" : ", " + where) + ": " +
                  what);
}

enum class Format { kAscii, kBinaryLittle, kBinaryBig };

enum class Scalar { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::size_t scalar_size(Scalar s) {
    switch (s) {
        case Scalar::kInt8:
        case Scalar::kUint8:
            return 1;
        case Scalar::kInt16:
        case Scalar::kUint16:
            return 2;
        case Scalar::kInt32:
        case Scalar::kUint32:
        case Scalar::kFloat32:
            return 4;
        case Scalar::kFloat64:
            return 8;
    }
    return 0;
}

bool is_integer(Scalar s) { return s != Scalar::kFloat32 && s != Scalar::kFloat64; }

bool parse_scalar_type(std::string_view name, Scalar* out) {
    static const struct {
        const char* name;
        Scalar type;
    } kTypes[] = {
        {"char", Scalar::kInt8},      {"int8", Scalar::kInt8},       {"uchar", Scalar::kUint8},
        {"uint8", Scalar::kUint8},    {"short", Scalar::kInt16},     {"int16", Scalar::kInt16},
        {"ushort", Scalar::kUint16},  {"uint16", Scalar::kUint16},   {"int", Scalar::kInt32},
        {"int32", Scalar::kInt32},    {"uint", Scalar::kUint32},     {"uint32", Scalar::kUint32},
        {"float", Scalar::kFloat32},  {"float32", Scalar::kFloat32}, {"double", Scalar::kFloat64},
        {"float64", Scalar::kFloat64}};
    for (const auto& t : kTypes) {
        if (name == t.name) {
            *out = t.type;
            return true;
        }
    }
    return false;
}

struct Property {
    std::string name;
    bool is_list = false;
    Scalar type = Scalar::kFloat32;      // scalar type, or the item type of a list
    Scalar count_type = Scalar::kUint8;  // only for lists
};

struct Element {
    std::string name;
    std::uint64_t count = 0;
    std::vector<Property> properties;
    std::size_t header_line = 0;

    /// Smallest number of body bytes one binary element can occupy (lists may be empty).
    std::size_t min_binary_size() const {
        std::size_t n = 0;
        for (const auto& p : properties) n += scalar_size(p.is_list ? p.count_type : p.type);
        return n;
    }
};

struct Header {
    Format format = Format::kAscii;
    std::vector<Element> elements;
    std::size_t body_offset = 0;  // byte offset of the first body byte
    std::size_t body_line = 0;    // line number of the first body line (ascii)
    Eigen::Vector3d origin_world_m = Eigen::Vector3d::Zero();  // kOriginComment, if present
};

std::string number_text(double value) {
    char text[32];
    std::snprintf(text, sizeof(text), "%.17g", value);
    return text;
}

std::vector<std::string_view> split_words(std::string_view line) {
    std::vector<std::string_view> words;
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
        const std::size_t start = i;
        while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
        if (i > start) words.push_back(line.substr(start, i - start));
    }
    return words;
}

/// The comment that carries TriangleMesh::origin_world_m:
/// "comment shine_origin_world_m <x> <y> <z> (world = origin + vertex)".
constexpr std::string_view kOriginComment = "shine_origin_world_m";

Eigen::Vector3d parse_origin_comment(const fs::path& path, const std::string& where,
                                     const std::vector<std::string_view>& words) {
    Eigen::Vector3d origin;
    for (int a = 0; a < 3; ++a) {
        const std::size_t w = 2 + static_cast<std::size_t>(a);
        if (w >= words.size()) {
            fail(path, where, "expected 'comment shine_origin_world_m <x> <y> <z>'");
        }
        const std::string text(words[w]);
        char* end = nullptr;
        origin[a] = std::strtod(text.c_str(), &end);
        if (end != text.c_str() + text.size() || !std::isfinite(origin[a])) {
            fail(path, where,
                 "the map origin '" + printable_excerpt(words[w]) + "' is not a finite number");
        }
    }
    return origin;
}

Header parse_header(const fs::path& path, std::string_view data) {
    Header header;
    std::size_t pos = 0;
    std::size_t line_no = 0;
    bool have_format = false;
    bool done = false;
    // Check the magic first: a binary file without newlines would otherwise only be reported as
    // "no end_header".
    if (data.substr(0, 4) != "ply\n" && data.substr(0, 5) != "ply\r\n") {
        fail(path, "line 1", "not a PLY file (the first line must be 'ply')");
    }
    while (!done) {
        if (pos >= data.size()) fail(path, "header", "ends without an 'end_header' line");
        std::size_t eol = data.find('\n', pos);
        if (eol == std::string_view::npos) {
            fail(path, "line " + std::to_string(line_no + 1),
                 "header ends without an 'end_header' line");
        }
        std::string_view line = data.substr(pos, eol - pos);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        ++line_no;
        pos = eol + 1;
        const std::string where = "line " + std::to_string(line_no);
        if (line_no == 1) {
            if (line != "ply") fail(path, where, "not a PLY file (first line must be 'ply')");
            continue;
        }
        const auto words = split_words(line);
        if (words.empty()) continue;
        const std::string_view key = words[0];
        if (key == "comment" && words.size() > 1 && words[1] == kOriginComment) {
            header.origin_world_m = parse_origin_comment(path, where, words);
            continue;
        }
        if (key == "comment" || key == "obj_info") continue;
        if (key == "format") {
            if (words.size() != 3) fail(path, where, "expected 'format <type> 1.0'");
            if (words[1] == "ascii") {
                header.format = Format::kAscii;
            } else if (words[1] == "binary_little_endian") {
                header.format = Format::kBinaryLittle;
            } else if (words[1] == "binary_big_endian") {
                header.format = Format::kBinaryBig;
            } else {
                fail(path, where,
                     "unknown format '" + printable_excerpt(words[1]) +
                         "' (expected ascii, binary_little_endian or "
                         "binary_big_endian)");
            }
            have_format = true;
        } else if (key == "element") {
            if (words.size() != 3) fail(path, where, "expected 'element <name> <count>'");
            Element e;
            e.name = std::string(words[1]);
            e.header_line = line_no;
            const auto c = words[2];
            const auto r = std::from_chars(c.data(), c.data() + c.size(), e.count);
            if (r.ec != std::errc() || r.ptr != c.data() + c.size()) {
                fail(path, where,
                     "element count '" + printable_excerpt(c) +
                         "' is not a non-negative integer below 2^64");
            }
            header.elements.push_back(std::move(e));
        } else if (key == "property") {
            if (header.elements.empty()) fail(path, where, "property before any element");
            Property p;
            if (words.size() >= 2 && words[1] == "list") {
                if (words.size() != 5) {
                    fail(path, where, "expected 'property list <count type> <item type> <name>'");
                }
                p.is_list = true;
                if (!parse_scalar_type(words[2], &p.count_type) || !is_integer(p.count_type)) {
                    fail(path, where,
                         "list count type '" + printable_excerpt(words[2]) +
                             "' is not an integer type");
                }
                if (!parse_scalar_type(words[3], &p.type)) {
                    fail(path, where,
                         "unknown property type '" + printable_excerpt(words[3]) + "'");
                }
                p.name = std::string(words[4]);
            } else {
                if (words.size() != 3) fail(path, where, "expected 'property <type> <name>'");
                if (!parse_scalar_type(words[1], &p.type)) {
                    fail(path, where,
                         "unknown property type '" + printable_excerpt(words[1]) + "'");
                }
                p.name = std::string(words[2]);
            }
            header.elements.back().properties.push_back(std::move(p));
        } else if (key == "end_header") {
            done = true;
        } else {
            fail(path, where, "unknown header keyword '" + printable_excerpt(key) + "'");
        }
    }
    if (!have_format) {
        fail(path, "header (lines 1-" + std::to_string(line_no) + ")", "has no 'format' line");
    }
    header.body_offset = pos;
    header.body_line = line_no + 1;

    // Check every declared count against the bytes that follow, before anything is allocated.
    const std::size_t body_bytes = data.size() - header.body_offset;
    std::size_t needed = 0;
    for (const auto& e : header.elements) {
        if (e.count == 0) continue;
        const std::string where = "line " + std::to_string(e.header_line);
        if (e.properties.empty()) {
            fail(path, where,
                 "element '" + printable_excerpt(e.name) + "' has " + std::to_string(e.count) +
                     " entries but no "
                     "properties");
        }
        // Binary: the fixed part of each entry; ascii: one character plus one separator per value.
        const std::size_t per_entry =
            header.format == Format::kAscii ? 2 * e.properties.size() : e.min_binary_size();
        const std::size_t remaining = body_bytes - std::min(needed, body_bytes);
        // The last ascii value needs no separator, hence the +1.
        const std::size_t slack = header.format == Format::kAscii ? 1 : 0;
        if (e.count > (remaining + slack) / per_entry) {
            fail(path, where,
                 "header declares " + std::to_string(e.count) + " '" + printable_excerpt(e.name) +
                     "' entries (at least " + std::to_string(per_entry) + " bytes each) but only " +
                     std::to_string(remaining) +
                     " bytes of data remain: truncated file or corrupt header");
        }
        needed += static_cast<std::size_t>(e.count) * per_entry;
    }
    return header;
}

/// Bounds-checked reader of binary PLY values.
class BinaryReader {
  public:
    BinaryReader(const fs::path& path, std::string_view data, std::size_t offset, bool big_endian)
        : path_(path), data_(data), pos_(offset), big_endian_(big_endian) {}

    double scalar(Scalar type) {
        const std::size_t n = scalar_size(type);
        if (data_.size() - pos_ < n) {
            fail(path_, "byte offset " + std::to_string(pos_),
                 "file is truncated (needed " + std::to_string(n) + " more bytes)");
        }
        unsigned char bytes[8];
        std::memcpy(bytes, data_.data() + pos_, n);
        pos_ += n;
        if (big_endian_ != kHostBigEndian) {
            for (std::size_t i = 0; i < n / 2; ++i) std::swap(bytes[i], bytes[n - 1 - i]);
        }
        switch (type) {
            case Scalar::kInt8:
                return static_cast<double>(load<std::int8_t>(bytes));
            case Scalar::kUint8:
                return static_cast<double>(load<std::uint8_t>(bytes));
            case Scalar::kInt16:
                return static_cast<double>(load<std::int16_t>(bytes));
            case Scalar::kUint16:
                return static_cast<double>(load<std::uint16_t>(bytes));
            case Scalar::kInt32:
                return static_cast<double>(load<std::int32_t>(bytes));
            case Scalar::kUint32:
                return static_cast<double>(load<std::uint32_t>(bytes));
            case Scalar::kFloat32:
                return static_cast<double>(load<float>(bytes));
            case Scalar::kFloat64:
                return load<double>(bytes);
        }
        return 0.0;
    }

    std::string where() const { return "byte offset " + std::to_string(pos_); }
    /// A cheap bookmark of the current position, for where_since().
    std::size_t mark() const { return pos_; }
    /// The place of a value that started at `mark`: its byte offset.
    std::string where_since(std::size_t mark) const {
        return "byte offset " + std::to_string(mark);
    }
    /// Bytes after the last element are tolerated: the counts were checked against the size, and
    /// some writers pad binary files.
    void finish() const {}

  private:
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    static constexpr bool kHostBigEndian = true;
#else
    static constexpr bool kHostBigEndian = false;
#endif

    template <typename T>
    static T load(const unsigned char* bytes) {
        T v;
        std::memcpy(&v, bytes, sizeof(T));
        return v;
    }

    const fs::path& path_;
    std::string_view data_;
    std::size_t pos_;
    bool big_endian_;
};

/// Tokenizer of ascii PLY bodies that tracks line numbers for messages.
class AsciiReader {
  public:
    AsciiReader(const fs::path& path, std::string_view data, std::size_t offset, std::size_t line)
        : path_(path), data_(data), pos_(offset), line_(line) {}

    double scalar(Scalar type) {
        while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) {
            if (data_[pos_] == '\n') ++line_;
            ++pos_;
        }
        if (pos_ >= data_.size()) fail(path_, where(), "file is truncated (expected a value)");
        const std::size_t start = pos_;
        while (pos_ < data_.size() && !std::isspace(static_cast<unsigned char>(data_[pos_]))) {
            ++pos_;
        }
        const char* first = data_.data() + start;
        const char* last = data_.data() + pos_;
        if (*first == '+') ++first;  // from_chars rejects a leading '+'
        double value = 0.0;
        const auto r = std::from_chars(first, last, value);
        if (r.ec != std::errc() || r.ptr != last || first == last) {
            fail(path_, where(),
                 "'" + printable_excerpt(data_.substr(start, pos_ - start)) + "' is not a number");
        }
        if (is_integer(type) && value != std::floor(value)) {
            fail(path_, where(),
                 "'" + printable_excerpt(data_.substr(start, pos_ - start)) +
                     "' is not an integer but the property is declared as an integer type");
        }
        return value;
    }

    std::string where() const { return "line " + std::to_string(line_); }
    std::size_t mark() const { return pos_; }
    /// The place of a value that started at `mark`: the line its last token is on.
    std::string where_since(std::size_t /*mark*/) const { return where(); }
    /// Rejects values after the last element: the header's counts are smaller than the data.
    void finish() {
        while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) {
            if (data_[pos_] == '\n') ++line_;
            ++pos_;
        }
        if (pos_ < data_.size()) {
            fail(path_, where(),
                 "'" + printable_excerpt(data_.substr(pos_, 20)) +
                     "' after the last element: the data holds more values than the header's "
                     "element counts declare");
        }
    }

  private:
    const fs::path& path_;
    std::string_view data_;
    std::size_t pos_;
    std::size_t line_;
};

const char* scalar_name(Scalar s) {
    switch (s) {
        case Scalar::kInt8:
            return "int8";
        case Scalar::kUint8:
            return "uint8";
        case Scalar::kInt16:
            return "int16";
        case Scalar::kUint16:
            return "uint16";
        case Scalar::kInt32:
            return "int32";
        case Scalar::kUint32:
            return "uint32";
        case Scalar::kFloat32:
            return "float32";
        case Scalar::kFloat64:
            return "float64";
    }
    return "";
}

struct ReadResult {
    TriangleMesh mesh;
    bool has_vertex_element = false;
    /// Points only: the stored values of the vertex element's time property (point_times.hpp).
    std::vector<double> raw_times;
    std::string time_field;  ///< "" without one
    Scalar time_type = Scalar::kFloat32;
    /// Points only: the vertex element's intensity (point_intensity.hpp), as stored.
    std::vector<float> intensity;
    std::string intensity_field;  ///< "" without one
};

/// Reads a list length and checks it is a sane non-negative integer.
template <typename Reader>
std::size_t read_list_count(Reader& reader, const Property& p, const fs::path& path) {
    const double c = reader.scalar(p.count_type);
    if (!(c >= 0.0) || c > 1e9) {
        fail(path, reader.where(),
             "invalid list length " + number_text(c) + " for property '" +
                 printable_excerpt(p.name) + "'");
    }
    return static_cast<std::size_t>(c);
}

template <typename Reader>
void read_body(Reader& reader, const Header& header, const fs::path& path, bool want_faces,
               ReadResult* result) {
    TriangleMesh& mesh = result->mesh;
    std::uint64_t face_count = 0;
    bool have_observed = false;
    std::vector<double> polygon;
    for (const Element& e : header.elements) {
        const std::string element_where = "element '" + printable_excerpt(e.name) +
                                          "' (header line " + std::to_string(e.header_line) + ")";
        if (e.name == "vertex") {
            if (result->has_vertex_element) fail(path, element_where, "second vertex element");
            result->has_vertex_element = true;
            int xyz_index[3] = {-1, -1, -1};
            for (std::size_t i = 0; i < e.properties.size(); ++i) {
                const Property& p = e.properties[i];
                for (int axis = 0; axis < 3; ++axis) {
                    if (p.name == std::string(1, static_cast<char>('x' + axis))) {
                        if (p.is_list)
                            fail(path, element_where, "property " + p.name + " is a list");
                        xyz_index[axis] = static_cast<int>(i);
                    }
                }
            }
            if (xyz_index[0] < 0 || xyz_index[1] < 0 || xyz_index[2] < 0) {
                fail(path, element_where, "vertex element lacks an x, y or z property");
            }
            // Scans: the per-point time, the first scalar property with a time field's name.
            int time_index = -1;
            if (!want_faces) {
                std::vector<std::string> scalar_names;
                for (const Property& p : e.properties) {
                    scalar_names.push_back(p.is_list ? std::string() : p.name);
                }
                time_index = find_point_time_field(scalar_names);
                if (time_index >= 0) {
                    result->time_field = e.properties[time_index].name;
                    result->time_type = e.properties[time_index].type;
                    result->raw_times.resize(static_cast<std::size_t>(e.count));
                }
            }
            // Scans: the intensity, the first property with an intensity field's name.
            int intensity_index = -1;
            if (!want_faces) {
                std::vector<std::string> names;
                for (const Property& p : e.properties) names.push_back(p.name);
                intensity_index = find_intensity_field(names);
                if (intensity_index >= 0) {
                    const Property& p = e.properties[intensity_index];
                    if (p.is_list) {
                        fail(path, element_where,
                             "intensity property '" + printable_excerpt(p.name) +
                                 "' is a list (expected one scalar per vertex)");
                    }
                    result->intensity_field = p.name;
                    result->intensity.resize(static_cast<std::size_t>(e.count));
                }
            }
            // Meshes: the appearance of mesh.ply (red, green, blue as 0..255; intensity).
            int rgb_index[3] = {-1, -1, -1};
            int mesh_intensity_index = -1;
            if (want_faces) {
                static const char* const kRgbNames[3] = {"red", "green", "blue"};
                for (std::size_t i = 0; i < e.properties.size(); ++i) {
                    const Property& p = e.properties[i];
                    if (p.is_list) continue;
                    for (int c = 0; c < 3; ++c) {
                        if (p.name == kRgbNames[c]) rgb_index[c] = static_cast<int>(i);
                    }
                    if (p.name == "intensity") mesh_intensity_index = static_cast<int>(i);
                }
                if (rgb_index[0] >= 0 && rgb_index[1] >= 0 && rgb_index[2] >= 0) {
                    mesh.vertex_rgb.resize(static_cast<std::size_t>(e.count));
                } else {
                    rgb_index[0] = rgb_index[1] = rgb_index[2] = -1;
                }
                if (mesh_intensity_index >= 0) {
                    mesh.vertex_intensity.resize(static_cast<std::size_t>(e.count));
                }
            }
            mesh.vertices.resize(static_cast<std::size_t>(e.count));
            for (std::uint64_t v = 0; v < e.count; ++v) {
                Eigen::Vector3f& out = mesh.vertices[static_cast<std::size_t>(v)];
                const std::size_t vertex_mark = reader.mark();
                for (std::size_t i = 0; i < e.properties.size(); ++i) {
                    const Property& p = e.properties[i];
                    if (p.is_list) {
                        const std::size_t n = read_list_count(reader, p, path);
                        for (std::size_t k = 0; k < n; ++k) reader.scalar(p.type);
                        continue;
                    }
                    const double value = reader.scalar(p.type);
                    for (int axis = 0; axis < 3; ++axis) {
                        if (static_cast<int>(i) == xyz_index[axis]) {
                            out[axis] = static_cast<float>(value);
                        }
                    }
                    if (static_cast<int>(i) == time_index) {
                        result->raw_times[static_cast<std::size_t>(v)] = value;
                    }
                    if (static_cast<int>(i) == intensity_index) {
                        result->intensity[static_cast<std::size_t>(v)] = static_cast<float>(value);
                    }
                    for (int c = 0; c < 3; ++c) {
                        if (static_cast<int>(i) == rgb_index[c]) {
                            const double level = std::isnan(value) ? 0.0 : value;
                            mesh.vertex_rgb[static_cast<std::size_t>(v)][c] =
                                static_cast<std::uint8_t>(std::clamp(level, 0.0, 255.0));
                        }
                    }
                    if (static_cast<int>(i) == mesh_intensity_index) {
                        mesh.vertex_intensity[static_cast<std::size_t>(v)] =
                            static_cast<float>(value);
                    }
                }
                // Scans may hold NaN for "no return" (preprocess_scan drops it); a mesh vertex
                // without a position has no meaning and would poison every distance to it.
                if (want_faces && !out.allFinite()) {
                    fail(path, reader.where_since(vertex_mark),
                         "vertex " + std::to_string(v) + " has a non-finite coordinate (" +
                             number_text(out.x()) + ", " + number_text(out.y()) + ", " +
                             number_text(out.z()) + ")");
                }
            }
            // Points only: later elements need not be read (nor can their counts be checked).
            if (!want_faces && &e != &header.elements.back()) return;
        } else if (e.name == "face" && want_faces) {
            if (face_count > 0) fail(path, element_where, "second face element");
            int index_property = -1;
            int observed_property = -1;
            for (std::size_t i = 0; i < e.properties.size(); ++i) {
                const Property& p = e.properties[i];
                if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
                    index_property = static_cast<int>(i);
                } else if (!p.is_list && p.name == "observed") {
                    observed_property = static_cast<int>(i);
                }
            }
            if (index_property < 0 && e.count > 0) {
                fail(path, element_where, "face element lacks a 'vertex_indices' list property");
            }
            face_count = e.count;
            have_observed = observed_property >= 0;
            // Most meshes are all triangles; polygons add more, which push_back handles.
            mesh.triangles.reserve(static_cast<std::size_t>(e.count));
            if (have_observed) mesh.face_observed.reserve(static_cast<std::size_t>(e.count));
            for (std::uint64_t f = 0; f < e.count; ++f) {
                polygon.clear();
                double observed = 0.0;
                for (std::size_t i = 0; i < e.properties.size(); ++i) {
                    const Property& p = e.properties[i];
                    if (static_cast<int>(i) == index_property) {
                        const std::size_t n = read_list_count(reader, p, path);
                        for (std::size_t k = 0; k < n; ++k) {
                            const double idx = reader.scalar(p.type);
                            if (!(idx >= 0.0) || idx != std::floor(idx) ||
                                idx > static_cast<double>(std::numeric_limits<int>::max())) {
                                fail(path, reader.where(),
                                     "face " + std::to_string(f) + " has invalid vertex index " +
                                         number_text(idx));
                            }
                            polygon.push_back(idx);
                        }
                    } else if (p.is_list) {
                        const std::size_t n = read_list_count(reader, p, path);
                        for (std::size_t k = 0; k < n; ++k) reader.scalar(p.type);
                    } else {
                        const double value = reader.scalar(p.type);
                        if (static_cast<int>(i) == observed_property) observed = value;
                    }
                }
                // Fan triangulation: (0, k, k+1). Faces with fewer than 3 corners carry no area
                // and are dropped.
                for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
                    mesh.triangles.emplace_back(static_cast<int>(polygon[0]),
                                                static_cast<int>(polygon[k]),
                                                static_cast<int>(polygon[k + 1]));
                    if (have_observed) mesh.face_observed.push_back(observed != 0.0 ? 1 : 0);
                }
            }
        } else {
            // Unknown element (or faces when only points are wanted): read past it.
            for (std::uint64_t k = 0; k < e.count; ++k) {
                for (const Property& p : e.properties) {
                    if (p.is_list) {
                        const std::size_t n = read_list_count(reader, p, path);
                        for (std::size_t j = 0; j < n; ++j) reader.scalar(p.type);
                    } else {
                        reader.scalar(p.type);
                    }
                }
            }
        }
    }
    reader.finish();
}

ReadResult parse_ply(std::string_view data, const fs::path& path, bool want_faces) {
    const Header header = parse_header(path, data);
    ReadResult result;
    result.mesh.origin_world_m = header.origin_world_m;
    if (header.format == Format::kAscii) {
        AsciiReader reader(path, data, header.body_offset, header.body_line);
        read_body(reader, header, path, want_faces, &result);
    } else {
        BinaryReader reader(path, data, header.body_offset, header.format == Format::kBinaryBig);
        read_body(reader, header, path, want_faces, &result);
    }
    if (!result.has_vertex_element) {
        fail(path, "header (lines 1-" + std::to_string(header.body_line - 1) + ")",
             "has no 'vertex' element");
    }
    const std::size_t nv = result.mesh.vertices.size();
    for (std::size_t t = 0; t < result.mesh.triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
            if (static_cast<std::size_t>(result.mesh.triangles[t][k]) >= nv) {
                fail(path, "triangle " + std::to_string(t),
                     "vertex index " + std::to_string(result.mesh.triangles[t][k]) +
                         " is out of range (the file has " + std::to_string(nv) + " vertices)");
            }
        }
    }
    return result;
}

/// Appends `value` in little-endian byte order at `out` and returns the next position.
template <typename T>
char* put_le(char* out, T value) {
    std::memcpy(out, &value, sizeof(T));
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(out[i], out[sizeof(T) - 1 - i]);
#endif
    return out + sizeof(T);
}

std::string header_text(std::size_t vertex_count, std::size_t face_count, bool with_faces,
                        bool with_observed,
                        const Eigen::Vector3d& origin_world_m = Eigen::Vector3d::Zero(),
                        bool with_time = false, bool with_rgb = false,
                        bool with_intensity = false) {
    std::string h = "ply\nformat binary_little_endian 1.0\ncomment written by ShineVDB\n";
    if (!origin_world_m.isZero(0.0)) {
        h += "comment " + std::string(kOriginComment);
        for (int a = 0; a < 3; ++a) h += " " + number_text(origin_world_m[a]);
        h += " (world = origin + vertex)\n";
    }
    h += "element vertex " + std::to_string(vertex_count) + "\n";
    h += "property float x\nproperty float y\nproperty float z\n";
    if (with_time) h += "property float t\n";
    if (with_rgb) h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    if (with_intensity) h += "property float intensity\n";
    if (with_faces) {
        h += "element face " + std::to_string(face_count) + "\n";
        h += "property list uchar int vertex_indices\n";
        if (with_observed) h += "property uchar observed\n";
    }
    h += "end_header\n";
    return h;
}

char* put_vertices(char* out, const std::vector<Eigen::Vector3f>& vertices) {
    for (const auto& v : vertices) {
        out = put_le(out, v.x());
        out = put_le(out, v.y());
        out = put_le(out, v.z());
    }
    return out;
}

}  // namespace
}  // namespace ply_internal

TriangleMesh read_ply_mesh(const fs::path& path) {
    return parse_ply_mesh(read_file_contents(path, "PLY file", "a .ply file"), path);
}

TriangleMesh parse_ply_mesh(std::string_view data, const fs::path& source) {
    return ply_internal::parse_ply(data, source, /*want_faces=*/true).mesh;
}

std::vector<Eigen::Vector3f> read_ply_points(const fs::path& path) {
    return parse_ply_points(read_file_contents(path, "PLY file", "a .ply file"), path);
}

std::vector<Eigen::Vector3f> parse_ply_points(std::string_view data, const fs::path& source) {
    return std::move(ply_internal::parse_ply(data, source, /*want_faces=*/false).mesh.vertices);
}

TimedPoints read_ply_scan(const fs::path& path, std::optional<double> stamp_s) {
    return parse_ply_scan(read_file_contents(path, "PLY file", "a .ply file"), path, stamp_s);
}

TimedPoints parse_ply_scan(std::string_view data, const fs::path& source,
                           std::optional<double> stamp_s) {
    using namespace ply_internal;
    ReadResult read = parse_ply(data, source, /*want_faces=*/false);
    TimedPoints scan;
    scan.points_sensor = std::move(read.mesh.vertices);
    if (!read.time_field.empty()) {
        scan.time_format.field = read.time_field;
        scan.time_format.type = scalar_name(read.time_type);
        scan.point_time_s = point_times_relative_s(read.raw_times, is_integer(read.time_type),
                                                   stamp_s, &scan.time_format);
    }
    scan.intensity = std::move(read.intensity);
    drop_unmeasured_intensity(scan.intensity);
    if (!scan.intensity.empty()) scan.intensity_field = read.intensity_field;
    return scan;
}

void write_ply_mesh(const fs::path& path, const TriangleMesh& mesh) {
    using namespace ply_internal;
    const std::size_t nv = mesh.vertices.size();
    const std::size_t nf = mesh.triangles.size();
    const bool with_observed = !mesh.face_observed.empty();
    if (with_observed && mesh.face_observed.size() != nf) {
        throw DataError("cannot write '" + path.string() + "': face_observed has " +
                        std::to_string(mesh.face_observed.size()) + " flags for " +
                        std::to_string(nf) + " triangles (must be empty or one per triangle)");
    }
    for (std::size_t t = 0; t < nf; ++t) {
        for (int k = 0; k < 3; ++k) {
            const int idx = mesh.triangles[t][k];
            if (idx < 0 || static_cast<std::size_t>(idx) >= nv) {
                throw DataError("cannot write '" + path.string() + "': triangle " +
                                std::to_string(t) + " refers to vertex " + std::to_string(idx) +
                                " but the mesh has " + std::to_string(nv) + " vertices");
            }
        }
    }
    const bool with_rgb = !mesh.vertex_rgb.empty();
    const bool with_intensity = !mesh.vertex_intensity.empty();
    const auto check_per_vertex = [&](std::size_t count, const char* what) {
        if (count != nv) {
            throw DataError("cannot write '" + path.string() + "': " + what + " has " +
                            std::to_string(count) + " entries for " + std::to_string(nv) +
                            " vertices (must be empty or one per vertex)");
        }
    };
    if (with_rgb) check_per_vertex(mesh.vertex_rgb.size(), "vertex_rgb");
    if (with_intensity) check_per_vertex(mesh.vertex_intensity.size(), "vertex_intensity");
    const std::string header = header_text(nv, nf, /*with_faces=*/true, with_observed,
                                           mesh.origin_world_m, false, with_rgb, with_intensity);
    const std::size_t face_bytes = 1 + 3 * sizeof(std::int32_t) + (with_observed ? 1 : 0);
    const std::size_t vertex_bytes =
        3 * sizeof(float) + (with_rgb ? 3 : 0) + (with_intensity ? sizeof(float) : 0);
    std::string buffer(header.size() + nv * vertex_bytes + nf * face_bytes, '\0');
    std::memcpy(buffer.data(), header.data(), header.size());
    char* out = buffer.data() + header.size();
    if (!with_rgb && !with_intensity) {
        out = put_vertices(out, mesh.vertices);
    } else {
        for (std::size_t v = 0; v < nv; ++v) {
            for (int a = 0; a < 3; ++a) out = put_le(out, mesh.vertices[v][a]);
            if (with_rgb) {
                for (int c = 0; c < 3; ++c) *out++ = static_cast<char>(mesh.vertex_rgb[v][c]);
            }
            if (with_intensity) out = put_le(out, mesh.vertex_intensity[v]);
        }
    }
    for (std::size_t t = 0; t < nf; ++t) {
        *out++ = 3;
        for (int k = 0; k < 3; ++k) out = put_le<std::int32_t>(out, mesh.triangles[t][k]);
        if (with_observed) *out++ = static_cast<char>(mesh.face_observed[t] != 0 ? 1 : 0);
    }
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    });
}

void write_ply_points(const fs::path& path, const std::vector<Eigen::Vector3f>& points) {
    using namespace ply_internal;
    const std::string header = header_text(points.size(), 0, /*with_faces=*/false, false);
    std::string buffer(header.size() + points.size() * 3 * sizeof(float), '\0');
    std::memcpy(buffer.data(), header.data(), header.size());
    put_vertices(buffer.data() + header.size(), points);
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    });
}

void write_ply_scan(const fs::path& path, const std::vector<Eigen::Vector3f>& points,
                    const std::vector<double>& point_time_s) {
    using namespace ply_internal;
    if (point_time_s.size() != points.size()) {
        throw DataError("cannot write '" + path.string() + "': " + std::to_string(points.size()) +
                        " points but " + std::to_string(point_time_s.size()) + " point times");
    }
    const std::string header = header_text(points.size(), 0, /*with_faces=*/false, false,
                                           Eigen::Vector3d::Zero(), /*with_time=*/true);
    std::string buffer(header.size() + points.size() * 4 * sizeof(float), '\0');
    std::memcpy(buffer.data(), header.data(), header.size());
    char* out = buffer.data() + header.size();
    for (std::size_t i = 0; i < points.size(); ++i) {
        for (int a = 0; a < 3; ++a) out = put_le(out, points[i][a]);
        out = put_le(out, static_cast<float>(point_time_s[i]));
    }
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    });
}

namespace {
/// A name beside `path` for a part of it being written; removed when done.
fs::path part_path(const fs::path& path, const char* part) {
    fs::path p = path;
    p += std::string(".") + part + ".tmp";
    return p;
}
}  // namespace

PlyMeshStreamWriter::PlyMeshStreamWriter(fs::path path, const Eigen::Vector3d& origin_world_m,
                                         TriangleMesh* copy)
    : path_(std::move(path)),
      origin_world_m_(origin_world_m),
      vertex_path_(part_path(path_, "vertices")),
      face_path_(part_path(path_, "faces")),
      copy_(copy) {
    if (copy_) {
        *copy_ = TriangleMesh{};
        copy_->origin_world_m = origin_world_m;
    }
    vertices_.open(vertex_path_, std::ios::binary | std::ios::trunc);
    faces_.open(face_path_, std::ios::binary | std::ios::trunc);
    if (!vertices_ || !faces_) {
        std::error_code ignored;
        fs::remove(vertex_path_, ignored);
        fs::remove(face_path_, ignored);
        throw IoError("cannot write '" + path_.string() + "': cannot create its temporary files '" +
                      vertex_path_.string() + "' and '" + face_path_.string() + "'");
    }
}

PlyMeshStreamWriter::~PlyMeshStreamWriter() {
    vertices_.close();
    faces_.close();
    std::error_code ignored;
    fs::remove(vertex_path_, ignored);
    fs::remove(face_path_, ignored);
}

void PlyMeshStreamWriter::check(const std::ostream& stream, const char* what) const {
    if (!stream) {
        throw IoError("cannot write '" + path_.string() + "': writing its " + what +
                      " failed (disk full?)");
    }
}

std::int32_t PlyMeshStreamWriter::add_vertex(const Eigen::Vector3f& vertex) {
    using ply_internal::put_le;
    if (num_vertices_ >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
        throw DataError("cannot write '" + path_.string() +
                        "': more vertices than a PLY int index can address");
    }
    char bytes[3 * sizeof(float)];
    char* out = bytes;
    for (int a = 0; a < 3; ++a) out = put_le(out, vertex[a]);
    vertices_.write(bytes, sizeof(bytes));
    check(vertices_, "vertices");
    if (copy_) copy_->vertices.push_back(vertex);
    return static_cast<std::int32_t>(num_vertices_++);
}

void PlyMeshStreamWriter::add_triangle(std::int32_t a, std::int32_t b, std::int32_t c) {
    using ply_internal::put_le;
    for (const std::int32_t index : {a, b, c}) {
        if (index < 0 || static_cast<std::size_t>(index) >= num_vertices_) {
            throw DataError("cannot write '" + path_.string() + "': triangle " +
                            std::to_string(num_triangles_) + " refers to vertex " +
                            std::to_string(index) + " but only " + std::to_string(num_vertices_) +
                            " vertices were added");
        }
    }
    char bytes[1 + 3 * sizeof(std::int32_t)];
    bytes[0] = 3;
    char* out = bytes + 1;
    for (const std::int32_t index : {a, b, c}) out = put_le(out, index);
    faces_.write(bytes, sizeof(bytes));
    check(faces_, "faces");
    if (copy_) copy_->triangles.emplace_back(a, b, c);
    ++num_triangles_;
}

void PlyMeshStreamWriter::commit() {
    vertices_.close();
    faces_.close();
    check(vertices_, "vertices");
    check(faces_, "faces");
    const std::string header = ply_internal::header_text(num_vertices_, num_triangles_,
                                                         /*with_faces=*/true,
                                                         /*with_observed=*/false, origin_world_m_);
    write_stream_atomically(path_, [&](std::ostream& out) {
        out.write(header.data(), static_cast<std::streamsize>(header.size()));
        for (const fs::path& part : {vertex_path_, face_path_}) {
            std::ifstream in(part, std::ios::binary);
            if (!in) {
                throw IoError("cannot write '" + path_.string() + "': its temporary file '" +
                              part.string() + "' disappeared");
            }
            if (fs::file_size(part) > 0) out << in.rdbuf();
        }
    });
}

}  // namespace shine
