#include "shine/sampling/point_kdtree.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "shine/core/error.hpp"

namespace shine {
namespace {

/// Nodes with at least this many points build their two children in parallel.
constexpr std::size_t kParallelBuildPoints = 32768;

/// Smallest and largest coordinate along `axis` (nanoflann's computeMinMax: starts from the first
/// point and replaces on strict comparisons).
void coordinate_range(const IndexedPoint* points, std::size_t count, int axis, float& min_value,
                      float& max_value) {
    min_value = points[0].position[axis];
    max_value = min_value;
    for (std::size_t i = 1; i < count; ++i) {
        const float v = points[i].position[axis];
        if (v < min_value) min_value = v;
        if (v > max_value) max_value = v;
    }
}

/// The first pass of nanoflann's planeSplit: moves the points below `cut` along `axis` to the
/// front, with nanoflann's exact swaps (they fix the order of the points in the leaves, and with
/// it the order in which equal distances are met); returns how many there are. `*on_cut` is set
/// if a point lies exactly on the cut (every point at or above it is looked at once).
std::size_t split_below(IndexedPoint* points, std::size_t count, int axis, float cut,
                        bool* on_cut) {
    std::size_t left = 0;
    std::size_t right = count - 1;
    bool met = false;
    for (;;) {
        while (left <= right && points[left].position[axis] < cut) ++left;
        while (right && left <= right && points[right].position[axis] >= cut) {
            met |= points[right].position[axis] == cut;
            --right;
        }
        if (left <= right) met |= points[left].position[axis] == cut;
        if (left > right || !right) break;
        std::swap(points[left], points[right]);
        ++left;
        --right;
    }
    *on_cut = met;
    return left;
}

/// Nodes of at most this many points are split by split_below_small.
constexpr std::size_t kSmallSplitPoints = 4096;

/// split_below for finite coordinates and at most kSmallSplitPoints points, with the same swaps
/// but without data-dependent branches (the scans of a small node stop at every few points, and
/// each stop costs a mispredicted branch): split_below swaps the points at or above the cut
/// among the first `below` ones (those that end below it), in order, with the points below the
/// cut among the others, from the last one back. Those pairs are listed by passes that only
/// count, then swapped.
std::size_t split_below_small(IndexedPoint* points, std::size_t count, int axis, float cut,
                              bool* on_cut) {
    std::uint8_t is_below[kSmallSplitPoints];
    std::size_t below = 0;
    std::size_t at_or_below = 0;
    for (std::size_t i = 0; i < count; ++i) {
        const float v = points[i].position[axis];
        is_below[i] = v < cut;
        below += v < cut;
        at_or_below += v <= cut;
    }
    *on_cut = at_or_below != below;
    std::uint16_t left[kSmallSplitPoints];
    std::uint16_t right[kSmallSplitPoints];
    std::size_t pairs = 0;
    for (std::size_t i = 0; i < below; ++i) {
        left[pairs] = static_cast<std::uint16_t>(i);
        pairs += !is_below[i];
    }
    std::size_t n_right = 0;
    for (std::size_t i = count; i-- > below;) {
        right[n_right] = static_cast<std::uint16_t>(i);
        n_right += is_below[i];
    }
    for (std::size_t p = 0; p < pairs; ++p) std::swap(points[left[p]], points[right[p]]);
    return below;
}

/// split_below, by split_below_small where it applies.
std::size_t split_below_any(IndexedPoint* points, std::size_t count, int axis, float cut,
                            bool finite, bool* on_cut) {
    return finite && count <= kSmallSplitPoints
               ? split_below_small(points, count, axis, cut, on_cut)
               : split_below(points, count, axis, cut, on_cut);
}

/// The second pass of nanoflann's planeSplit over [lim1, count), whose points are all at or above
/// the cut: moves those on the cut to the front of that range; returns the end of them (lim2).
std::size_t split_on(IndexedPoint* points, std::size_t count, int axis, float cut,
                     std::size_t lim1) {
    std::size_t left = lim1;
    std::size_t right = count - 1;
    for (;;) {
        while (left <= right && points[left].position[axis] <= cut) ++left;
        while (right && left <= right && points[right].position[axis] > cut) --right;
        if (left > right || !right) break;
        std::swap(points[left], points[right]);
        ++left;
        --right;
    }
    return left;
}

}  // namespace

/// One query: nanoflann's KNNResultSet, whose worst distance until k points are found is the
/// search bound it was initialised with. Distances and slots are kept in separate arrays of 16
/// entries (64 for k > 16), whole SSE registers, sorted, the unused entries at +infinity, so that
/// an insertion is a few branch-free vector operations; entries past the k-th are not part of the
/// result (the insertions keep the whole array sorted, so they do not change what the first k
/// are).
struct PointKdTree::Search {
    static constexpr int kSmallBlocks = 4;
    static constexpr int kLargeBlocks = kMaxNeighbors / 4;

    float query[3];
    int k;
    float bound;  ///< points must be strictly nearer than this until k are found
    int count = 0;
    alignas(16) float distance_sq[kMaxNeighbors];
    alignas(16) std::uint32_t slot[kMaxNeighbors];

    Search(const Eigen::Vector3f& q, int k_in, float bound_in)
        : query{q.x(), q.y(), q.z()}, k(k_in), bound(bound_in) {
        const int entries = 4 * (k <= 4 * kSmallBlocks ? kSmallBlocks : kLargeBlocks);
        std::fill(distance_sq, distance_sq + entries, std::numeric_limits<float>::infinity());
        std::fill(slot, slot + entries, 0u);
    }

    float worst() const { return count < k ? bound : distance_sq[k - 1]; }

    /// KNNResultSet::addPoint for a finite distance: the entry goes after those at equal
    /// distance, and is dropped if it is no nearer than the k-th.
    void add(float d, std::uint32_t s) {
        if (!(d < worst())) return;
#if defined(__SSE2__)
        if (k <= 4 * kSmallBlocks) {
            insert<kSmallBlocks>(d, s);
        } else {
            insert<kLargeBlocks>(d, s);
        }
#else
        int i = count;
        for (; i > 0 && distance_sq[i - 1] > d; --i) {
            if (i < k) {
                distance_sq[i] = distance_sq[i - 1];
                slot[i] = slot[i - 1];
            }
        }
        distance_sq[i] = d;
        slot[i] = s;
#endif
        if (count < k) ++count;
    }

#if defined(__SSE2__)
    /// Inserts a distance (not negative) nearer than the k-th into kBlocks blocks of four
    /// entries: its place is after the entries at most d, the entries farther than d move up one
    /// (a block's last one into the next block). Lane by lane, with `up` the entries moved up
    /// (lane 0 of the first block +0): the new distance is max(up, min(old, d)), which is old
    /// before the place, d at it and up after it; the slot is the new one where old > d but not
    /// up > d (the place), up's where up > d, old's elsewhere.
    template <int kBlocks>
    void insert(float d, std::uint32_t s) {
        const __m128 dv = _mm_set1_ps(d);
        const __m128i sv = _mm_set1_epi32(static_cast<int>(s));
        __m128i carry_d = _mm_setzero_si128();
        __m128i carry_s = _mm_setzero_si128();
        for (int b = 0; b < kBlocks; ++b) {
            float* dp = distance_sq + 4 * b;
            __m128i* sp = reinterpret_cast<__m128i*>(slot + 4 * b);
            const __m128i old_d = _mm_castps_si128(_mm_load_ps(dp));
            const __m128i old_s = _mm_load_si128(sp);
            const __m128 up_d = _mm_castsi128_ps(_mm_or_si128(_mm_slli_si128(old_d, 4), carry_d));
            const __m128i up_s = _mm_or_si128(_mm_slli_si128(old_s, 4), carry_s);
            carry_d = _mm_srli_si128(old_d, 12);
            carry_s = _mm_srli_si128(old_s, 12);
            const __m128i at_or_after = _mm_castps_si128(_mm_cmpgt_ps(_mm_castsi128_ps(old_d), dv));
            const __m128i after = _mm_castps_si128(_mm_cmpgt_ps(up_d, dv));
            _mm_store_ps(dp, _mm_max_ps(up_d, _mm_min_ps(_mm_castsi128_ps(old_d), dv)));
            const __m128i new_or_old =
                _mm_or_si128(_mm_and_si128(at_or_after, sv), _mm_andnot_si128(at_or_after, old_s));
            _mm_store_si128(
                sp, _mm_or_si128(_mm_and_si128(after, up_s), _mm_andnot_si128(after, new_or_old)));
        }
    }
#endif
};

PointKdTree::PointKdTree(std::vector<IndexedPoint> points, int leaf_size) : leaf_size_(leaf_size) {
    if (leaf_size < 1 || leaf_size > kMaxLeafSize) {
        throw ConfigError("PointKdTree: leaf size " + std::to_string(leaf_size) +
                          " is outside [1, " + std::to_string(kMaxLeafSize) + "]");
    }
    const std::size_t n = points.size();
    if (n >= std::numeric_limits<std::uint32_t>::max()) {
        throw DataError("PointKdTree: " + std::to_string(n) +
                        " points are more than a 32-bit index can address; split the set");
    }
    if (n == 0) return;
    // nanoflann's computeBoundingBox: the first point, then strict comparisons. For finite
    // coordinates that is the minimum and maximum, which the parallel reduction finds in any
    // order; a NaN makes the result depend on the order, so then the serial loop decides.
    struct Range {
        Box box;
        bool finite;
    };
    const auto first_box = [](const IndexedPoint& p) {
        Box box;
        for (int a = 0; a < 3; ++a) box[a] = {p.position[a], p.position[a]};
        return box;
    };
    Range range = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, 65536), Range{first_box(points[0]), true},
        [&](const tbb::blocked_range<std::size_t>& r, Range acc) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                const Eigen::Vector3f& p = points[i].position;
                acc.finite = acc.finite && p.allFinite();
                for (int a = 0; a < 3; ++a) {
                    acc.box[a].low = std::min(acc.box[a].low, p[a]);
                    acc.box[a].high = std::max(acc.box[a].high, p[a]);
                }
            }
            return acc;
        },
        [](Range a, const Range& b) {
            for (int i = 0; i < 3; ++i) {
                a.box[i].low = std::min(a.box[i].low, b.box[i].low);
                a.box[i].high = std::max(a.box[i].high, b.box[i].high);
            }
            a.finite = a.finite && b.finite;
            return a;
        });
    root_box_ = range.box;
    finite_ = range.finite;
    if (!range.finite) {
        root_box_ = first_box(points[0]);
        for (std::size_t i = 1; i < n; ++i) {
            for (int a = 0; a < 3; ++a) {
                const float v = points[i].position[a];
                if (v < root_box_[a].low) root_box_[a].low = v;
                if (v > root_box_[a].high) root_box_[a].high = v;
            }
        }
    }
    nodes_.reserve(n / 4 + 16);
    height_ = build(points.data(), 0, n, root_box_, nodes_).height;

    // Three floats of padding: a leaf's last group of four may read past its end.
    x_.resize(n + 3, 0.0f);
    y_.resize(n + 3, 0.0f);
    z_.resize(n + 3, 0.0f);
    index_.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 65536), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            x_[i] = points[i].position.x();
            y_[i] = points[i].position.y();
            z_[i] = points[i].position.z();
            index_[i] = points[i].index;
        }
    });
}

/// nanoflann's divideTree and middleSplit_ over points [begin, end) inside `cell` (the root box
/// cut by the ancestors' split values); appends the subtree to `nodes` depth first and returns
/// the bounding box of its points and its height.
PointKdTree::Subtree PointKdTree::build(IndexedPoint* points, std::size_t begin, std::size_t end,
                                        const Box& cell, std::vector<Node>& nodes) const {
    const std::size_t self = nodes.size();
    nodes.emplace_back();
    const std::size_t count = end - begin;
    IndexedPoint* p = points + begin;
    if (count <= static_cast<std::size_t>(leaf_size_)) {
        Box box;
        for (int a = 0; a < 3; ++a) box[a] = {p[0].position[a], p[0].position[a]};
        for (std::size_t i = 1; i < count; ++i) {
            for (int a = 0; a < 3; ++a) {
                if (box[a].low > p[i].position[a]) box[a].low = p[i].position[a];
                if (box[a].high < p[i].position[a]) box[a].high = p[i].position[a];
            }
        }
        nodes[self].second_child_or_begin = static_cast<std::uint32_t>(begin);
        nodes[self].axis_or_leaf_size = kLeafFlag | static_cast<std::uint32_t>(count);
        return {box, 1};
    }

    // middleSplit_: among the axes whose cell side is (almost) the longest, the one along which
    // the points spread most; cut at the cell's middle, clamped to the points' range.
    const float eps = 0.00001f;
    float max_span = cell[0].high - cell[0].low;
    for (int a = 1; a < 3; ++a) {
        const float span = cell[a].high - cell[a].low;
        if (span > max_span) max_span = span;
    }
    int candidates = 0;
    int only_candidate = 0;
    for (int a = 0; a < 3; ++a) {
        if (cell[a].high - cell[a].low > (1 - eps) * max_span) {
            ++candidates;
            only_candidate = a;
        }
    }
    int axis = 0;
    float cut = 0.0f;
    std::size_t lim1 = 0;
    bool on_cut = true;
    if (finite_ && candidates == 1) {
        // The usual case (all of them on the street): one axis to cut, at the middle of the cell
        // unless all the points lie on one side of it (then nanoflann clamps the cut to their
        // range). A partition at the middle tells which, and has moved nothing when they do: so
        // the range is only looked up then. (With a NaN among the points, which is on neither
        // side, the range must come first, as in nanoflann.)
        axis = only_candidate;
        const float middle = (cell[axis].low + cell[axis].high) / 2;
        cut = middle;
        lim1 = split_below_any(p, count, axis, cut, finite_, &on_cut);
        if (lim1 == 0 || lim1 == count) {
            float min_value, max_value;
            coordinate_range(p, count, axis, min_value, max_value);
            if (middle < min_value) {
                cut = min_value;
            } else if (middle > max_value) {
                cut = max_value;
            }
            if (cut != middle) lim1 = split_below_any(p, count, axis, cut, finite_, &on_cut);
        }
    } else {
        // middleSplit_ as it is: the candidate axes' ranges (axis 0's if there is no candidate),
        // the widest spread, the cut clamped to its range.
        float min_value[3], max_value[3];
        for (int a = 0; a < 3; ++a) {
            if (cell[a].high - cell[a].low > (1 - eps) * max_span || a == 0) {
                coordinate_range(p, count, a, min_value[a], max_value[a]);
            }
        }
        float max_spread = -1.0f;
        for (int a = 0; a < 3; ++a) {
            if (cell[a].high - cell[a].low > (1 - eps) * max_span) {
                const float spread = max_value[a] - min_value[a];
                if (spread > max_spread) {
                    axis = a;
                    max_spread = spread;
                }
            }
        }
        const float middle = (cell[axis].low + cell[axis].high) / 2;
        cut = middle;
        if (middle < min_value[axis]) {
            cut = min_value[axis];
        } else if (middle > max_value[axis]) {
            cut = max_value[axis];
        }
        lim1 = split_below_any(p, count, axis, cut, finite_, &on_cut);
    }
    // The second pass of planeSplit has nothing to move when no point lies on the cut (unless a
    // NaN does, which stops its scans like a point on the wrong side).
    const std::size_t lim2 = on_cut || !finite_ ? split_on(p, count, axis, cut, lim1) : lim1;
    std::size_t index;
    if (lim1 > count / 2) {
        index = lim1;
    } else if (lim2 < count / 2) {
        index = lim2;
    } else {
        index = count / 2;
    }

    Box left_cell = cell;
    left_cell[axis].high = cut;
    Box right_cell = cell;
    right_cell[axis].low = cut;
    Subtree left, right;
    std::size_t second_child;
    if (count >= kParallelBuildPoints) {
        std::vector<Node> right_nodes;
        right_nodes.reserve((end - begin - index) / 4 + 16);
        tbb::parallel_invoke(
            [&] { left = build(points, begin, begin + index, left_cell, nodes); },
            [&] { right = build(points, begin + index, end, right_cell, right_nodes); });
        second_child = nodes.size() - self;
        nodes.insert(nodes.end(), right_nodes.begin(), right_nodes.end());
    } else {
        left = build(points, begin, begin + index, left_cell, nodes);
        second_child = nodes.size() - self;
        right = build(points, begin + index, end, right_cell, nodes);
    }
    Node& node = nodes[self];
    node.div_low = left.box[axis].high;
    node.div_high = right.box[axis].low;
    node.second_child_or_begin = static_cast<std::uint32_t>(second_child);
    node.axis_or_leaf_size = static_cast<std::uint32_t>(axis);
    Subtree subtree{{}, 1 + std::max(left.height, right.height)};
    for (int a = 0; a < 3; ++a) {
        subtree.box[a].low = std::min(left.box[a].low, right.box[a].low);
        subtree.box[a].high = std::max(left.box[a].high, right.box[a].high);
    }
    return subtree;
}

/// A subtree the walk has still to decide on: nanoflann's searchLevel visits the other child of
/// a node after the nearer one's subtree, if the lower bound of its distance is within the k-th
/// distance as it is by then. Kept on an explicit stack (last in, first out: the recursion's
/// order).
struct PointKdTree::Pending {
    std::uint32_t node;
    float min_distance_sq;
    std::array<float, 3> axis_distance_sq;
};

/// nanoflann's searchLevel from `root`: the nearer child first, then the other one unless the
/// incrementally updated lower bound of its distance exceeds the k-th distance by then.
void PointKdTree::search(Search& s, Pending* stack, const Pending& root) const {
    int top = 0;
    Pending pending = root;
    for (;;) {
        std::size_t node_index = pending.node;
        // The k-th distance does not change on the way down to a leaf, and only shrinks after:
        // a subtree already beyond it would be left out when its turn comes, and is not pushed.
        const float worst = s.worst();
        for (;;) {
            const Node& node = nodes_[node_index];
            if (node.axis_or_leaf_size & kLeafFlag) {
                scan_leaf(s, node.second_child_or_begin, node.axis_or_leaf_size & ~kLeafFlag);
                break;
            }
            const int axis = static_cast<int>(node.axis_or_leaf_size);
            const float value = s.query[axis];
            const float diff1 = value - node.div_low;
            const float diff2 = value - node.div_high;
            std::size_t best, other;
            float cut_distance_sq;
            if ((diff1 + diff2) < 0) {
                best = node_index + 1;
                other = node_index + node.second_child_or_begin;
                cut_distance_sq = (value - node.div_high) * (value - node.div_high);
            } else {
                best = node_index + node.second_child_or_begin;
                other = node_index + 1;
                cut_distance_sq = (value - node.div_low) * (value - node.div_low);
            }
            // The nearer child keeps the bound; the other one's is updated along this axis.
            Pending& next = stack[top];
            next.node = static_cast<std::uint32_t>(other);
            next.min_distance_sq =
                pending.min_distance_sq + cut_distance_sq - pending.axis_distance_sq[axis];
            next.axis_distance_sq = pending.axis_distance_sq;
            next.axis_distance_sq[axis] = cut_distance_sq;
            top += next.min_distance_sq <= worst;
            node_index = best;
        }
        do {
            if (top == 0) return;
            pending = stack[--top];
        } while (!(pending.min_distance_sq <= s.worst()));
    }
}

/// The points of a leaf in their order, as nanoflann's searchLevel checks them.
void PointKdTree::scan_leaf(Search& s, std::size_t begin, std::size_t count) const {
    const float* x = x_.data() + begin;
    const float* y = y_.data() + begin;
    const float* z = z_.data() + begin;
    // nanoflann compares with the worst distance as it was when the leaf was entered, and
    // addPoint drops what is no longer nearer than the k-th by the time it comes. Comparing with
    // the k-th distance as it is by then instead keeps the same points (while fewer than k are
    // found, both are the bound) and skips the insertions that would drop them.
#if defined(__SSE2__)
    // Four points at a time, in point_distance_sq's order of operations (the coordinate arrays
    // are padded, so the last group may read past the leaf; those lanes are masked off).
    const __m128 qx = _mm_set1_ps(s.query[0]);
    const __m128 qy = _mm_set1_ps(s.query[1]);
    const __m128 qz = _mm_set1_ps(s.query[2]);
    for (std::size_t group = 0; group < count; group += 4) {
        const __m128 worst_v = _mm_set1_ps(s.worst());
        const __m128 dx = _mm_sub_ps(qx, _mm_loadu_ps(x + group));
        const __m128 dy = _mm_sub_ps(qy, _mm_loadu_ps(y + group));
        const __m128 dz = _mm_sub_ps(qz, _mm_loadu_ps(z + group));
        const __m128 d =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
        unsigned mask = static_cast<unsigned>(_mm_movemask_ps(_mm_cmplt_ps(d, worst_v)));
        if (count - group < 4) mask &= (1u << (count - group)) - 1u;
        if (mask == 0) continue;
        alignas(16) float distance_sq[4];
        _mm_store_ps(distance_sq, d);
        do {
            const int lane = __builtin_ctz(mask);
            s.add(distance_sq[lane], static_cast<std::uint32_t>(begin + group + lane));
            mask &= mask - 1;
        } while (mask != 0);
    }
#else
    for (std::size_t i = 0; i < count; ++i) {
        const float dx = s.query[0] - x[i];
        const float dy = s.query[1] - y[i];
        const float dz = s.query[2] - z[i];
        const float distance_sq = (dx * dx + dy * dy) + dz * dz;
        if (distance_sq < s.worst()) s.add(distance_sq, static_cast<std::uint32_t>(begin + i));
    }
#endif
}

int PointKdTree::nearest(const Eigen::Vector3f& query, int k, float max_distance_sq,
                         PointNeighbor* neighbors) const {
    if (k <= 0 || nodes_.empty()) return 0;
    Search s(query, std::min(k, kMaxNeighbors),
             std::nextafter(max_distance_sq, std::numeric_limits<float>::infinity()));
    // computeInitialDistances: the distance from the query to the root box, per axis.
    Pending root{0, 0.0f, {0.0f, 0.0f, 0.0f}};
    for (int a = 0; a < 3; ++a) {
        if (s.query[a] < root_box_[a].low) {
            root.axis_distance_sq[a] =
                (s.query[a] - root_box_[a].low) * (s.query[a] - root_box_[a].low);
            root.min_distance_sq += root.axis_distance_sq[a];
        }
        if (s.query[a] > root_box_[a].high) {
            root.axis_distance_sq[a] =
                (s.query[a] - root_box_[a].high) * (s.query[a] - root_box_[a].high);
            root.min_distance_sq += root.axis_distance_sq[a];
        }
    }
    // At most one pending subtree per level.
    constexpr int kStackOnFrame = 128;
    Pending on_frame[kStackOnFrame];
    std::vector<Pending> on_heap;
    Pending* stack = on_frame;
    if (height_ > kStackOnFrame) {
        on_heap.resize(static_cast<std::size_t>(height_));
        stack = on_heap.data();
    }
    search(s, stack, root);
    for (int i = 0; i < s.count; ++i) {
        const std::uint32_t slot = s.slot[i];
        neighbors[i].distance_sq = s.distance_sq[i];
        neighbors[i].index = index_[slot];
        neighbors[i].position = Eigen::Vector3f(x_[slot], y_[slot], z_[slot]);
    }
    return s.count;
}

}  // namespace shine
