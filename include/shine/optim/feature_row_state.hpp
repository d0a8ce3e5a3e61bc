// The optimiser's per-row state of the feature table, kept only where the map is being trained.
//
// Every feature row the optimiser touches has, next to the feature itself (which the map holds):
//   Adam's two moments and step count;
//   the anchor theta* of the importance regulariser (incremental mode): the row's value when the
//   current scan began, snapshotted when the scan first touches the row (for a row not touched
//   since the last scan ended, that is the converged value of paper Eq. (3));
//   the float32 master copy of a float16 map (mixed precision).
// A row's state is one contiguous block, its counters (step, anchor scan, master flag) next to its
// floats and the block padded to a multiple of 32 bytes, so a touched row costs two cache misses
// (8 features with anchors: 128 bytes) instead of one per table. Blocks live in pages of
// kRowsPerPage consecutive rows (rows are appended in scan order, so a page holds one stretch of
// the drive), allocated when a row of the page is first touched and freed by release_unused_pages()
// once no row of the page was touched for a while: on a long drive the optimiser's memory follows
// the active region, not the whole map. Pages are stretches of slabs, 2 MiB-aligned mappings that
// may use transparent huge pages (HugePageRegion): rows are read in random order, and with 4 KiB
// pages nearly every row would also miss the TLB. A released row starts again from zero moments
// (and from its rounded value as master copy), as a row does the first time it is trained.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "shine/core/huge_page_region.hpp"

namespace shine {

class BinaryReader;
class BinaryWriter;

class FeatureRowState {
  public:
    static constexpr std::size_t kRowsPerPage = 4096;

    /// One row's state; pointers into its page.
    struct Row {
        float* first_moment;          ///< dim floats
        float* second_moment;         ///< dim floats
        float* anchor;                ///< dim floats, or nullptr without anchors
        float* master;                ///< dim floats, or nullptr without a master copy
        std::uint32_t* step;          ///< Adam steps taken by the row
        std::uint32_t* anchor_scan;   ///< 1 + the scan whose start the anchor holds; 0: none
        std::uint32_t* master_valid;  ///< 0 until the master copy was filled
    };

    FeatureRowState(int dim, bool with_anchor, bool with_master);
    ~FeatureRowState();
    FeatureRowState(FeatureRowState&&) noexcept;
    FeatureRowState& operator=(FeatureRowState&&) noexcept;

    /// Covers rows [0, num_rows) (pages are still only allocated when used).
    void resize(std::size_t num_rows);
    /// The state of `row`, allocating its page (zeroed) if needed and marking the page used in
    /// `scan`. Safe to call concurrently for different rows, also of one page.
    Row touch(std::int32_t row, std::uint32_t scan) { return row_in_block(touch_block(row, scan)); }
    /// As touch(), but returns only the start of the row's block, which row_in_block() turns into
    /// the Row: one pointer is what a loop that requests rows ahead keeps in flight (a Row copied
    /// through memory costs more than the pointers it holds).
    float* touch_block(std::int32_t row, std::uint32_t scan);
    /// The Row whose block starts at `block` (a touch_block() result).
    Row row_in_block(float* block) const {
        const std::size_t d = static_cast<std::size_t>(dim_);
        std::uint32_t* ints = reinterpret_cast<std::uint32_t*>(block + floats_per_row_);
        return {block,
                block + d,
                with_anchor_ ? block + 2 * d : nullptr,
                with_master_ ? block + (2 + with_anchor_) * d : nullptr,
                ints,
                ints + 1,
                ints + 2};
    }
    /// Frees the pages no row of which was touched in scan `oldest_kept` or later. Not concurrent
    /// with touch(). Returns the number of pages freed.
    std::size_t release_unused_pages(std::uint32_t oldest_kept);

    int dim() const { return dim_; }
    bool has_anchor() const { return with_anchor_; }
    bool has_master() const { return with_master_; }
    std::size_t resident_pages() const;
    /// Bytes of the allocated pages and the page table.
    std::size_t memory_bytes() const;

    /// Every allocated page (for a checkpoint); load() replaces the state and checks the layout.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    struct Page;
    Page* page_of(std::size_t page_index);
    /// Where page `page_index` lives in its slab.
    void* page_storage(std::size_t page_index) const;
    /// Frees the page (if allocated) and hands its memory back; it reads as zeros when reused.
    void drop_page(std::size_t page_index);
    std::size_t page_bytes() const;
    /// A row's floats and its counters inside its page (slot = row mod kRowsPerPage).
    float* floats_at(const Page& page, std::size_t slot) const;
    std::uint32_t* counters_at(const Page& page, std::size_t slot) const;

    int dim_;
    bool with_anchor_;
    bool with_master_;
    std::size_t floats_per_row_;
    std::size_t words_per_row_;  ///< a row's block: its floats, its counters, padding
    std::size_t pages_per_slab_;
    std::size_t num_rows_ = 0;
    std::vector<std::atomic<Page*>> pages_;
    std::vector<HugePageRegion> slabs_;  ///< slab s holds pages [s, s + 1) * pages_per_slab_
};

}  // namespace shine
