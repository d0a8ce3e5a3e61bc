// Structure check of OpenVDB files: every length, count and offset is bounded before it is used,
// following the layout OpenVDB 10 reads (io/Archive, tree/RootNode, InternalNode, LeafNode,
// io/Compression.h readCompressedValues, io/DelayedLoadMetadata).
#include "shine/io/vdb_file_check.hpp"

#include <array>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace vdb_file_check_internal {
namespace {

constexpr std::int64_t kMagic = 0x56444220;  // "VDB " as OpenVDB writes it
// Per-grid compression flags (OpenVDB 3.0); older files have another header layout.
constexpr std::uint32_t kMinFormatVersion = 222;
// Multi-pass I/O (OpenVDB 4 to 10 write this); a newer layout is not known to this check.
constexpr std::uint32_t kMaxFormatVersion = 224;
constexpr std::size_t kUuidChars = 36;
// io::COMPRESS_ZIP, COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC.
constexpr std::uint32_t kCompressZip = 0x1;
constexpr std::uint32_t kCompressActiveMask = 0x2;
constexpr std::uint32_t kCompressBlosc = 0x4;
constexpr std::uint32_t kKnownCompressionFlags =
    kCompressZip | kCompressActiveMask | kCompressBlosc;
constexpr char kUniqueNameSeparator = '\x1e';
constexpr std::string_view kHalfFloatSuffix = "_HalfFloat";
constexpr std::size_t kBloscHeaderBytes = 16;  // BLOSC_MIN_HEADER_LENGTH
// Per-node flag of readCompressedValues: NO_MASK_OR_INACTIVE_VALS (0) .. NO_MASK_AND_ALL_VALS (6).
constexpr int kMaxNodeMetadata = 6;

/// Value sizes of OpenVDB's fixed-size metadata types. OpenVDB reads sizeof(T) bytes whatever
/// byte count the file gives, so a mismatch would put every later read out of step.
std::size_t fixed_metadata_size(std::string_view type) {
    static const struct {
        const char* name;
        std::size_t bytes;
    } kTypes[] = {{"bool", 1},    {"half", 2},   {"float", 4},  {"double", 8}, {"int8", 1},
                  {"uint8", 1},   {"int16", 2},  {"uint16", 2}, {"int32", 4},  {"uint32", 4},
                  {"int64", 8},   {"vec2i", 8},  {"vec2s", 8},  {"vec2d", 16}, {"vec3u8", 3},
                  {"vec3u16", 6}, {"vec3i", 12}, {"vec3s", 12}, {"vec3d", 24}, {"vec4i", 16},
                  {"vec4s", 16},  {"vec4d", 32}, {"mat3s", 36}, {"mat3d", 72}, {"mat4s", 64},
                  {"mat4d", 128}, {"quats", 16}, {"quatd", 32}};
    for (const auto& t : kTypes) {
        if (type == t.name) return t.bytes;
    }
    return 0;  // variable size (string) or a type OpenVDB keeps as opaque bytes
}

/// Bytes a transform's map reads after its type name; 0 for an unknown map type.
std::size_t map_bytes(std::string_view type) {
    static const struct {
        const char* name;
        std::size_t bytes;
    } kMaps[] = {{"AffineMap", 128},
                 {"UnitaryMap", 128},
                 {"ScaleMap", 5 * 24},
                 {"UniformScaleMap", 5 * 24},
                 {"TranslationMap", 24},
                 {"ScaleTranslateMap", 6 * 24},
                 {"UniformScaleTranslateMap", 6 * 24}};
    for (const auto& m : kMaps) {
        if (type == m.name) return m.bytes;
    }
    return 0;
}

/// How a tree's values are stored: Tree_<value>_5_4_3 for the value types this check knows.
struct ValueLayout {
    std::size_t bytes = 0;       ///< sizeof(ValueType)
    std::size_t half_bytes = 0;  ///< stored size in a _HalfFloat grid (real types only)
};

bool standard_tree_layout(std::string_view type, ValueLayout* out) {
    static const struct {
        const char* tree;
        ValueLayout layout;
    } kTrees[] = {{"Tree_float_5_4_3", {4, 2}},  {"Tree_double_5_4_3", {8, 2}},
                  {"Tree_int32_5_4_3", {4, 0}},  {"Tree_int64_5_4_3", {8, 0}},
                  {"Tree_vec3i_5_4_3", {12, 0}}, {"Tree_vec3s_5_4_3", {12, 6}},
                  {"Tree_vec3d_5_4_3", {24, 6}}};
    for (const auto& t : kTrees) {
        if (type == t.tree) {
            *out = t.layout;
            return true;
        }
    }
    return false;
}

constexpr int kLeafLog2 = 3;  // 8^3 voxels
using LeafMask = std::array<unsigned char, (1u << (3 * kLeafLog2)) / 8>;

std::size_t count_on(const unsigned char* mask, std::size_t bytes) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < bytes; ++i)
        n += static_cast<std::size_t>(__builtin_popcount(mask[i]));
    return n;
}

/// Bounds-checked little-endian reads from a stream of known size.
class Reader {
  public:
    Reader(std::istream& in, std::uint64_t size, const fs::path& path, const std::string& kind)
        : in_(in), size_(size), limit_(size), path_(path), kind_(kind) {}

    [[noreturn]] void fail(std::uint64_t offset, const std::string& problem) const {
        throw IoError(kind_ + " '" + path_.string() + "', byte offset " + std::to_string(offset) +
                      ": " + problem);
    }

    std::uint64_t pos() const { return pos_; }
    std::uint64_t size() const { return size_; }
    std::uint64_t remaining() const { return limit_ - pos_; }

    /// Reads end at `limit` (the end of a grid section) until set_limit(size()).
    void set_limit(std::uint64_t limit, const std::string& section) {
        limit_ = limit;
        section_ = section;
    }

    void seek(std::uint64_t offset) {
        pos_ = offset;
        in_.clear();
        in_.seekg(static_cast<std::streamoff>(offset));
    }

    /// Checks that `n` bytes of `what` fit before the limit.
    void need(std::uint64_t n, const std::string& what) const {
        if (n > remaining()) {
            fail(pos_, "the file is truncated or corrupt: " + what + " needs " + std::to_string(n) +
                           " bytes but only " + std::to_string(remaining()) + " remain" +
                           (limit_ < size_ ? " in " + section_ : "") + " (the file has " +
                           std::to_string(size_) + " bytes)");
        }
    }

    void read(void* out, std::size_t n, const std::string& what) {
        need(n, what);
        in_.read(static_cast<char*>(out), static_cast<std::streamsize>(n));
        if (static_cast<std::size_t>(in_.gcount()) != n) {
            fail(pos_, "read error in " + what + " (file changed while reading?)");
        }
        pos_ += n;
    }

    void skip(std::uint64_t n, const std::string& what) {
        need(n, what);
        seek(pos_ + n);
    }

    template <typename T>
    T value(const std::string& what) {
        T v;
        read(&v, sizeof(T), what);
        return v;
    }

    std::string string(const std::string& what) {
        const std::uint32_t length = value<std::uint32_t>(what + " length");
        need(length, what);
        std::string s(length, '\0');
        if (length > 0) read(s.data(), length, what);
        return s;
    }

  private:
    std::istream& in_;
    std::uint64_t size_;
    std::uint64_t limit_;
    std::uint64_t pos_ = 0;
    std::string section_;
    const fs::path& path_;
    const std::string& kind_;
};

/// A blosc block header (c-blosc 1.x): c-blosc trusts its sizes, so they must match what
/// OpenVDB expects and the bytes the file holds. With `padded`, blocks of fewer than 128 bytes
/// may be stored padded to 128 (OpenVDB's compression::bloscCompress, BLOSC_PAD_BYTES).
void check_blosc_header(Reader& r, std::uint64_t block_bytes, std::uint64_t expected_bytes,
                        const std::string& what, bool padded = false) {
    constexpr std::uint32_t kBloscPadBytes = 128;
    const std::uint64_t at = r.pos();
    if (block_bytes < kBloscHeaderBytes) {
        r.fail(at, what + ": a blosc block of " + std::to_string(block_bytes) +
                       " bytes is shorter than its 16-byte header");
    }
    unsigned char header[kBloscHeaderBytes];
    r.read(header, sizeof(header), what + " blosc header");
    std::uint32_t nbytes, blocksize, cbytes;
    std::memcpy(&nbytes, header + 4, 4);
    std::memcpy(&blocksize, header + 8, 4);
    std::memcpy(&cbytes, header + 12, 4);
    const bool size_ok = nbytes == expected_bytes ||
                         (padded && nbytes == kBloscPadBytes && expected_bytes <= nbytes);
    if (!size_ok || cbytes != block_bytes || header[3] == 0 ||
        (nbytes > 0 && (blocksize == 0 || blocksize > nbytes))) {
        r.fail(at, what + ": blosc header (" + std::to_string(nbytes) + " bytes, " +
                       std::to_string(cbytes) + " compressed, blocks of " +
                       std::to_string(blocksize) + ") does not match the " +
                       std::to_string(expected_bytes) + " bytes expected in a " +
                       std::to_string(block_bytes) + "-byte block");
    }
    r.skip(block_bytes - kBloscHeaderBytes, what);
}

/// io::readData: `expected_bytes` of values, raw or as one zip/blosc chunk whose int64 size
/// prefix is negative for data stored uncompressed.
void check_data(Reader& r, std::uint64_t expected_bytes, std::uint32_t compression,
                const std::string& what) {
    if ((compression & (kCompressBlosc | kCompressZip)) == 0) {
        r.skip(expected_bytes, what);
        return;
    }
    const std::uint64_t at = r.pos();
    const std::int64_t n = r.value<std::int64_t>(what + " size");
    if (n <= 0) {
        // OpenVDB reads -n bytes into a buffer of expected_bytes before comparing the two.
        if (n == std::numeric_limits<std::int64_t>::min() ||
            static_cast<std::uint64_t>(-n) != expected_bytes) {
            r.fail(at, what + ": " +
                           std::to_string(n == std::numeric_limits<std::int64_t>::min() ? 0 : -n) +
                           " uncompressed bytes where " + std::to_string(expected_bytes) +
                           " are expected");
        }
        r.skip(expected_bytes, what);
        return;
    }
    r.need(static_cast<std::uint64_t>(n), what);
    if (compression & kCompressBlosc) {
        check_blosc_header(r, static_cast<std::uint64_t>(n), expected_bytes, what);
    } else {
        r.skip(static_cast<std::uint64_t>(n), what);  // zlib's inflate is bounded by its output
    }
}

/// The per-node value block of io::readCompressedValues.
struct NodeValues {
    std::size_t count;       ///< values in the node (destCount)
    std::size_t active;      ///< active values (valueMask.countOn())
    std::size_t mask_bytes;  ///< bytes of the node's mask (selection mask)
};

void check_compressed_values(Reader& r, const NodeValues& node, const ValueLayout& layout,
                             bool half, std::uint32_t compression, const std::string& what) {
    const std::uint64_t at = r.pos();
    const auto metadata = r.value<std::int8_t>(what + " flag");
    if (metadata < 0 || metadata > kMaxNodeMetadata) {
        r.fail(at, what + " has an unknown value-compression flag " +
                       std::to_string(static_cast<int>(metadata)));
    }
    // NO_MASK_AND_ONE_INACTIVE_VAL, MASK_AND_ONE_INACTIVE_VAL, MASK_AND_TWO_INACTIVE_VALS: full
    // precision inactive values, even in half-float grids.
    if (metadata == 2 || metadata == 4 || metadata == 5) r.skip(layout.bytes, what);
    if (metadata == 5) r.skip(layout.bytes, what);
    // MASK_AND_*: the selection mask between the two inactive values.
    if (metadata >= 3 && metadata <= 5) r.skip(node.mask_bytes, what + " selection mask");
    std::size_t count = node.count;
    if ((compression & kCompressActiveMask) && metadata != kMaxNodeMetadata) count = node.active;
    const std::size_t element = half && layout.half_bytes > 0 ? layout.half_bytes : layout.bytes;
    check_data(r, static_cast<std::uint64_t>(count) * element, compression, what + " values");
}

/// What the topology pass learns for the buffer pass: every leaf's value mask, in the order
/// OpenVDB reads the buffers (root children by origin, then child-mask order).
struct Topology {
    std::vector<LeafMask> leaves;
};

std::string coord_text(const std::int32_t c[3]) {
    return "(" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) +
           ")";
}

/// InternalNode::readTopology of a node of 2^log2 children per axis; children are internal
/// nodes of log2 - 1 down to the leaves (5-4-3 tree).
void check_internal_topology(Reader& r, int log2, const ValueLayout& layout, bool half,
                             std::uint32_t compression, const std::string& what,
                             Topology* topology) {
    const std::size_t num_values = std::size_t{1} << (3 * log2);
    const std::size_t mask_bytes = num_values / 8;
    std::vector<unsigned char> child_mask(mask_bytes), value_mask(mask_bytes);
    r.read(child_mask.data(), mask_bytes, what + " child mask");
    r.read(value_mask.data(), mask_bytes, what + " value mask");
    check_compressed_values(r, {num_values, count_on(value_mask.data(), mask_bytes), mask_bytes},
                            layout, half, compression, what + " tile");
    for (std::size_t i = 0; i < num_values; ++i) {
        if (!(child_mask[i / 8] & (1u << (i % 8)))) continue;
        if (log2 - 1 == 4) {
            check_internal_topology(r, 4, layout, half, compression, what, topology);
        } else {
            LeafMask mask;
            r.read(mask.data(), mask.size(), what + " leaf value mask");
            topology->leaves.push_back(mask);
        }
    }
}

/// Grid::readTopology of a standard 5-4-3 tree.
Topology check_tree_topology(Reader& r, const ValueLayout& layout, bool half,
                             std::uint32_t compression, const std::string& what) {
    Topology topology;
    const std::uint64_t buffers_at = r.pos();
    const auto buffer_count = r.value<std::int32_t>(what + " buffer count");
    if (buffer_count != 1) {
        r.fail(buffers_at, what + " has " + std::to_string(buffer_count) +
                               " buffers per node (OpenVDB 3 and later write 1)");
    }
    r.skip(layout.bytes, what + " background");
    const std::uint64_t counts_at = r.pos();
    const auto num_tiles = r.value<std::uint32_t>(what + " root tile count");
    const auto num_children = r.value<std::uint32_t>(what + " root child count");
    const std::uint64_t tile_bytes = 3 * 4 + layout.bytes + 1;
    // A child holds at least its origin and two 4096-byte masks.
    const std::uint64_t min_child_bytes = 3 * 4 + 2 * 4096;
    if (num_tiles > r.remaining() / tile_bytes ||
        num_children > (r.remaining() - num_tiles * tile_bytes) / min_child_bytes) {
        r.fail(counts_at, what + ": " + std::to_string(num_tiles) + " root tiles and " +
                              std::to_string(num_children) + " root children cannot fit in " +
                              std::to_string(r.remaining()) + " bytes");
    }
    // OpenVDB keys the root table by origin: a repeated origin leaks or replaces a node, and the
    // buffers are read in origin order. Files written by OpenVDB list origins in that order.
    constexpr std::int32_t kChildDim = 1 << (5 + 4 + 3);
    std::array<std::int32_t, 3> previous{};
    bool have_previous = false;
    const auto check_origin = [&](const std::int32_t c[3], std::uint64_t at, const char* kind) {
        const std::array<std::int32_t, 3> origin{c[0], c[1], c[2]};
        for (int k = 0; k < 3; ++k) {
            if (c[k] % kChildDim != 0) {
                r.fail(at, what + ": root " + kind + " origin " + coord_text(c) +
                               " is not a multiple of 4096");
            }
        }
        if (have_previous && !(previous < origin)) {
            r.fail(at, what + ": root " + kind + " origin " + coord_text(c) +
                           " is out of order or repeated");
        }
        previous = origin;
        have_previous = true;
    };
    for (std::uint32_t i = 0; i < num_tiles; ++i) {
        const std::uint64_t at = r.pos();
        std::int32_t c[3];
        r.read(c, sizeof(c), what + " root tile origin");
        check_origin(c, at, "tile");
        r.skip(layout.bytes + 1, what + " root tile");
    }
    have_previous = false;
    for (std::uint32_t i = 0; i < num_children; ++i) {
        const std::uint64_t at = r.pos();
        std::int32_t c[3];
        r.read(c, sizeof(c), what + " root child origin");
        check_origin(c, at, "child");
        check_internal_topology(r, 5, layout, half, compression, what + " node " + coord_text(c),
                                &topology);
    }
    return topology;
}

/// Grid::readBuffers: per leaf, its value mask again and its values.
void check_tree_buffers(Reader& r, const Topology& topology, const ValueLayout& layout, bool half,
                        std::uint32_t compression, const std::string& what) {
    for (std::size_t i = 0; i < topology.leaves.size(); ++i) {
        const std::uint64_t at = r.pos();
        LeafMask mask;
        r.read(mask.data(), mask.size(), what + " leaf value mask");
        // OpenVDB uses one of the two copies depending on the stream; they must agree.
        if (mask != topology.leaves[i]) {
            r.fail(at, what + ": the value mask of leaf " + std::to_string(i) +
                           " differs from the one in the topology");
        }
        check_compressed_values(r,
                                {mask.size() * 8, count_on(mask.data(), mask.size()), mask.size()},
                                layout, half, compression, what + " leaf " + std::to_string(i));
    }
}

/// Grid::readTransform (Transform::read): a map type name and that map's fixed-size values.
void check_transform(Reader& r, const std::string& what, int depth = 0) {
    const std::uint64_t at = r.pos();
    const std::string type = r.string(what + " transform type");
    if (type == "NonlinearFrustumMap" && depth == 0) {
        r.skip(6 * 8 + 2 * 8, what + " frustum");  // bounding box, taper, depth
        check_transform(r, what + " frustum", depth + 1);
        return;
    }
    const std::size_t bytes = map_bytes(type);
    if (bytes == 0) {
        r.fail(at, what + " has an unknown transform type '" + printable_excerpt(type) + "'");
    }
    r.skip(bytes, what + " transform");
}

/// io::DelayedLoadMetadata ("__delayedload") value: OpenVDB sizes its buffers from the counts
/// inside and hands compressed parts to blosc, so they must agree with the entry's byte count.
struct DelayedLoad {
    std::uint32_t count = 0;
};

DelayedLoad check_delayed_load(Reader& r, std::uint32_t entry_bytes, const std::string& what) {
    DelayedLoad d;
    const std::uint64_t start = r.pos();
    if (entry_bytes == 0) return d;
    r.set_limit(start + entry_bytes, what);
    d.count = r.value<std::uint32_t>(what + " count");
    // The leaf masks (one byte each), then the compressed sizes (8 bytes each) unless the size
    // word is 0xffffffff.
    for (const std::size_t element : {std::size_t{1}, std::size_t{8}}) {
        const auto bytes = r.value<std::uint32_t>(what + " block size");
        if (element == 8 && bytes == std::numeric_limits<std::uint32_t>::max()) break;
        const std::uint64_t expected = static_cast<std::uint64_t>(d.count) * element;
        if (bytes > 0) {
            check_blosc_header(r, bytes, expected, what, /*padded=*/true);
        } else {
            r.skip(expected, what);
        }
    }
    r.set_limit(r.size(), "");
    r.seek(start + entry_bytes);
    return d;
}

/// Reads a MetaMap: the names of its entries, the value of the string entry `wanted` (into
/// *wanted_value) and the count of a delayed-load entry (into *delayed).
std::vector<std::string> check_metadata(Reader& r, const std::string& what,
                                        std::uint64_t section_end, const std::string& wanted = "",
                                        std::string* wanted_value = nullptr,
                                        DelayedLoad* delayed = nullptr) {
    const std::uint64_t count_at = r.pos();
    const auto count = r.value<std::int32_t>(what + " count");
    // Each entry holds at least a name length, a type length and a byte count.
    constexpr std::uint64_t kMinEntryBytes = 12;
    if (count < 0 || static_cast<std::uint64_t>(count) > r.remaining() / kMinEntryBytes) {
        r.fail(count_at, what + " count " + std::to_string(count) + " is impossible with " +
                             std::to_string(r.remaining()) + " bytes left");
    }
    std::vector<std::string> names;
    for (std::int32_t i = 0; i < count; ++i) {
        const std::string name = r.string(what + " name");
        const std::string quoted = what + " '" + printable_excerpt(name) + "'";
        const std::string type = r.string(quoted + " type");
        const std::uint64_t size_at = r.pos();
        const auto bytes = r.value<std::uint32_t>(quoted + " size");
        const std::size_t fixed = fixed_metadata_size(type);
        if (fixed != 0 && bytes != fixed) {
            r.fail(size_at, quoted + " of type " + printable_excerpt(type) + " has " +
                                std::to_string(bytes) + " bytes, expected " +
                                std::to_string(fixed));
        }
        r.need(bytes, quoted + " value");
        if (type == "__delayedload") {
            const DelayedLoad d = check_delayed_load(r, bytes, quoted);
            if (delayed) *delayed = d;
            r.set_limit(section_end, "the grid header");
        } else if (wanted_value != nullptr && name == wanted && type == "string") {
            wanted_value->assign(bytes, '\0');
            if (bytes > 0) r.read(wanted_value->data(), bytes, quoted + " value");
        } else {
            r.skip(bytes, quoted + " value");
        }
        names.push_back(name);
    }
    return names;
}

VdbFileInfo check(std::istream& in, std::uint64_t size, const fs::path& path,
                  const std::string& kind) {
    Reader r(in, size, path, kind);
    VdbFileInfo info;
    if (size < 8 || r.value<std::int64_t>("magic number") != kMagic) {
        r.fail(0, "not an OpenVDB file (it does not start with the magic number \"VDB \")");
    }
    info.format_version = r.value<std::uint32_t>("format version");
    if (info.format_version < kMinFormatVersion) {
        r.fail(8, "format version " + std::to_string(info.format_version) + " is older than " +
                      std::to_string(kMinFormatVersion) +
                      " (OpenVDB 3.0); re-save it with a current OpenVDB");
    }
    if (info.format_version > kMaxFormatVersion) {
        r.fail(8, "format version " + std::to_string(info.format_version) + " is newer than " +
                      std::to_string(kMaxFormatVersion) +
                      ", the newest this build reads; was it written by a newer OpenVDB?");
    }
    r.value<std::uint32_t>("library major version");
    r.value<std::uint32_t>("library minor version");
    const std::uint64_t flag_at = r.pos();
    if (r.value<std::uint8_t>("grid-offset flag") == 0) {
        r.fail(flag_at, "written as a stream, without grid offsets; save it as a file");
    }
    r.skip(kUuidChars, "UUID");
    info.file_metadata = check_metadata(r, "file metadata", size);

    const std::uint64_t count_at = r.pos();
    const auto grid_count = r.value<std::int32_t>("grid count");
    // A descriptor holds at least three string lengths and three offsets.
    constexpr std::uint64_t kMinDescriptorBytes = 3 * 4 + 3 * 8;
    if (grid_count < 0 ||
        static_cast<std::uint64_t>(grid_count) > r.remaining() / kMinDescriptorBytes) {
        r.fail(count_at, "grid count " + std::to_string(grid_count) + " is impossible with " +
                             std::to_string(r.remaining()) + " bytes left");
    }
    for (std::int32_t g = 0; g < grid_count; ++g) {
        const std::string grid_what = "grid " + std::to_string(g);
        VdbGridInfo grid;
        const std::string unique_name = r.string(grid_what + " name");
        grid.name = unique_name.substr(0, unique_name.find(kUniqueNameSeparator));
        const std::string quoted = grid_what + " '" + printable_excerpt(grid.name) + "'";
        grid.type = r.string(quoted + " type");
        if (grid.type.size() >= kHalfFloatSuffix.size() &&
            grid.type.compare(grid.type.size() - kHalfFloatSuffix.size(), kHalfFloatSuffix.size(),
                              kHalfFloatSuffix) == 0) {
            grid.type.resize(grid.type.size() - kHalfFloatSuffix.size());
            grid.half_float = true;
        }
        const bool instance = !r.string(quoted + " instance parent name").empty();
        const std::uint64_t offsets_at = r.pos();
        const auto grid_pos = r.value<std::int64_t>(quoted + " grid offset");
        const auto block_pos = r.value<std::int64_t>(quoted + " block offset");
        const auto end_pos = r.value<std::int64_t>(quoted + " end offset");
        const auto descriptor_end = static_cast<std::int64_t>(r.pos());
        if (!(descriptor_end <= grid_pos && grid_pos <= block_pos && block_pos <= end_pos)) {
            r.fail(offsets_at, quoted + " has inconsistent offsets (grid " +
                                   std::to_string(grid_pos) + ", voxel data " +
                                   std::to_string(block_pos) + ", end " + std::to_string(end_pos) +
                                   "; the descriptor ends at " + std::to_string(descriptor_end) +
                                   ")");
        }
        if (static_cast<std::uint64_t>(end_pos) > r.size()) {
            r.fail(offsets_at, "the file is truncated: " + quoted + " ends at byte " +
                                   std::to_string(end_pos) + " but the file has " +
                                   std::to_string(r.size()) + " bytes");
        }
        grid.grid_offset = static_cast<std::uint64_t>(grid_pos);
        grid.end_offset = static_cast<std::uint64_t>(end_pos);
        ValueLayout layout;
        if (!standard_tree_layout(grid.type, &layout)) {
            r.fail(offsets_at + 4, quoted + " has tree type '" + printable_excerpt(grid.type) +
                                       "', whose voxel data this check cannot verify (it knows "
                                       "float, double, int32, int64 and vec3 grids with the "
                                       "standard 5-4-3 tree)");
        }

        // The grid header, up to the voxel data: compression flags, metadata, transform and,
        // unless the grid shares another grid's tree, the tree topology.
        r.seek(grid.grid_offset);
        r.set_limit(static_cast<std::uint64_t>(block_pos), "the grid header");
        const std::uint64_t flags_at = r.pos();
        const auto compression = r.value<std::uint32_t>(quoted + " compression flags");
        if ((compression & ~kKnownCompressionFlags) != 0) {
            r.fail(flags_at,
                   quoted + " has unknown compression flags " + std::to_string(compression));
        }
        grid.grid_class = "unknown";
        DelayedLoad delayed;
        check_metadata(r, quoted + " metadata", static_cast<std::uint64_t>(block_pos), "class",
                       &grid.grid_class, &delayed);
        check_transform(r, quoted);
        if (!instance) {
            const Topology topology =
                check_tree_topology(r, layout, grid.half_float, compression, quoted);
            if (r.pos() != static_cast<std::uint64_t>(block_pos)) {
                r.fail(r.pos(), quoted + ": the topology ends at byte " + std::to_string(r.pos()) +
                                    " but the voxel data starts at " + std::to_string(block_pos));
            }
            if (delayed.count > topology.leaves.size()) {
                r.fail(flags_at, quoted + " delayed-load metadata lists " +
                                     std::to_string(delayed.count) + " leaves but the tree has " +
                                     std::to_string(topology.leaves.size()));
            }
            r.set_limit(static_cast<std::uint64_t>(end_pos), "the grid's voxel data");
            check_tree_buffers(r, topology, layout, grid.half_float, compression, quoted);
            if (r.pos() != static_cast<std::uint64_t>(end_pos)) {
                r.fail(r.pos(), quoted + ": the voxel data ends at byte " +
                                    std::to_string(r.pos()) + " but the grid ends at " +
                                    std::to_string(end_pos));
            }
        }
        r.set_limit(r.size(), "");
        info.grids.push_back(std::move(grid));
        r.seek(static_cast<std::uint64_t>(end_pos));
    }
    return info;
}

}  // namespace
}  // namespace vdb_file_check_internal

VdbFileInfo check_vdb_file(const fs::path& path, const std::string& kind) {
    std::error_code ec;
    if (!fs::exists(path, ec))
        throw IoError(kind + " '" + path.string() + "': file does not exist");
    if (!fs::is_regular_file(path, ec)) {
        throw IoError(kind + " '" + path.string() + "': not a regular file, expected a .vdb file");
    }
    const std::uint64_t size = fs::file_size(path, ec);
    if (ec) throw IoError(kind + " '" + path.string() + "': cannot determine the file size");
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw IoError(kind + " '" + path.string() + "': cannot open for reading (permissions?)");
    }
    return vdb_file_check_internal::check(in, size, path, kind);
}

VdbFileInfo check_vdb_bytes(std::string_view data, const fs::path& source,
                            const std::string& kind) {
    std::istringstream in{std::string(data)};
    return vdb_file_check_internal::check(in, data.size(), source, kind);
}

}  // namespace shine
