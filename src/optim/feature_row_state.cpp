#include "shine/optim/feature_row_state.hpp"

#include <algorithm>
#include <string>

#include "shine/io/binary_stream.hpp"

namespace shine {

namespace {
constexpr std::size_t kCounters = 3;         ///< per row: step, anchor_scan, master_valid
constexpr std::size_t kBlockAlignWords = 8;  ///< blocks start on 32-byte boundaries

std::size_t block_words(std::size_t floats_per_row) {
    return (floats_per_row + kCounters + kBlockAlignWords - 1) / kBlockAlignWords *
           kBlockAlignWords;
}
}  // namespace

/// kRowsPerPage blocks of words_per_row_ 4-byte words: the row's floats, then its counters, then
/// padding (floats_at / counters_at). The counters share the floats' cache lines: a touched row
/// costs two cache misses for the state (with 8 features and anchors, one 128-byte block)
/// instead of three. The storage is the page's stretch of its slab (zeros when first used).
struct FeatureRowState::Page {
    void* storage;
    std::atomic<std::uint32_t> last_scan{0};

    explicit Page(void* storage_in) : storage(storage_in) {}
};

std::size_t FeatureRowState::page_bytes() const {
    return kRowsPerPage * words_per_row_ * sizeof(std::uint32_t);
}

float* FeatureRowState::floats_at(const Page& page, std::size_t slot) const {
    return static_cast<float*>(page.storage) + slot * words_per_row_;
}

std::uint32_t* FeatureRowState::counters_at(const Page& page, std::size_t slot) const {
    return static_cast<std::uint32_t*>(page.storage) + slot * words_per_row_ + floats_per_row_;
}

FeatureRowState::FeatureRowState(int dim, bool with_anchor, bool with_master)
    : dim_(dim),
      with_anchor_(with_anchor),
      with_master_(with_master),
      floats_per_row_(static_cast<std::size_t>(dim) * (2 + with_anchor + with_master)),
      words_per_row_(block_words(floats_per_row_)),
      pages_per_slab_(std::max<std::size_t>(1, HugePageRegion::kHugePageBytes / page_bytes())) {}

FeatureRowState::~FeatureRowState() {
    for (auto& p : pages_) delete p.load();
}

FeatureRowState::FeatureRowState(FeatureRowState&& other) noexcept
    : dim_(other.dim_),
      with_anchor_(other.with_anchor_),
      with_master_(other.with_master_),
      floats_per_row_(other.floats_per_row_),
      words_per_row_(other.words_per_row_),
      pages_per_slab_(other.pages_per_slab_),
      num_rows_(other.num_rows_),
      pages_(std::move(other.pages_)),
      slabs_(std::move(other.slabs_)) {
    other.num_rows_ = 0;
}

FeatureRowState& FeatureRowState::operator=(FeatureRowState&& other) noexcept {
    if (this != &other) {
        for (auto& p : pages_) delete p.load();
        dim_ = other.dim_;
        with_anchor_ = other.with_anchor_;
        with_master_ = other.with_master_;
        floats_per_row_ = other.floats_per_row_;
        words_per_row_ = other.words_per_row_;
        pages_per_slab_ = other.pages_per_slab_;
        num_rows_ = other.num_rows_;
        pages_ = std::move(other.pages_);
        slabs_ = std::move(other.slabs_);
        other.num_rows_ = 0;
    }
    return *this;
}

void FeatureRowState::resize(std::size_t num_rows) {
    num_rows_ = std::max(num_rows_, num_rows);
    const std::size_t needed = (num_rows_ + kRowsPerPage - 1) / kRowsPerPage;
    if (needed <= pages_.size()) return;
    // std::atomic is not movable: grow by building a new table.
    std::vector<std::atomic<Page*>> grown(needed);
    for (std::size_t i = 0; i < pages_.size(); ++i) grown[i].store(pages_[i].load());
    pages_ = std::move(grown);
    // Slabs are mapped here, where nothing runs concurrently; they take memory only where touched.
    const std::size_t slabs = (needed + pages_per_slab_ - 1) / pages_per_slab_;
    while (slabs_.size() < slabs) slabs_.emplace_back(pages_per_slab_ * page_bytes());
}

void* FeatureRowState::page_storage(std::size_t page_index) const {
    return static_cast<char*>(slabs_[page_index / pages_per_slab_].data()) +
           page_index % pages_per_slab_ * page_bytes();
}

void FeatureRowState::drop_page(std::size_t page_index) {
    Page* page = pages_[page_index].exchange(nullptr);
    if (!page) return;
    slabs_[page_index / pages_per_slab_].discard(page_index % pages_per_slab_ * page_bytes(),
                                                 page_bytes());
    delete page;
}

FeatureRowState::Page* FeatureRowState::page_of(std::size_t page_index) {
    Page* page = pages_[page_index].load(std::memory_order_acquire);
    if (page) return page;
    // First use: whoever installs a page first wins; the others drop their record of it (the
    // storage is the same stretch of the slab, still zeros), so the result does not depend on
    // which thread won.
    auto fresh = std::make_unique<Page>(page_storage(page_index));
    if (pages_[page_index].compare_exchange_strong(page, fresh.get(), std::memory_order_acq_rel)) {
        return fresh.release();
    }
    return page;
}

float* FeatureRowState::touch_block(std::int32_t row, std::uint32_t scan) {
    const std::size_t r = static_cast<std::size_t>(row);
    Page* page = page_of(r / kRowsPerPage);
    if (page->last_scan.load(std::memory_order_relaxed) != scan) {
        page->last_scan.store(scan, std::memory_order_relaxed);
    }
    return floats_at(*page, r % kRowsPerPage);
}

std::size_t FeatureRowState::release_unused_pages(std::uint32_t oldest_kept) {
    std::size_t released = 0;
    for (std::size_t i = 0; i < pages_.size(); ++i) {
        const Page* page = pages_[i].load();
        if (page && page->last_scan.load() < oldest_kept) {
            drop_page(i);
            ++released;
        }
    }
    return released;
}

std::size_t FeatureRowState::resident_pages() const {
    return static_cast<std::size_t>(std::count_if(
        pages_.begin(), pages_.end(), [](const auto& p) { return p.load() != nullptr; }));
}

std::size_t FeatureRowState::memory_bytes() const {
    return resident_pages() * page_bytes() + pages_.capacity() * sizeof(std::atomic<Page*>) +
           slabs_.capacity() * sizeof(HugePageRegion);
}

void FeatureRowState::save(BinaryWriter& out) const {
    out.tag("feature row state");
    out.value<std::int32_t>(dim_);
    out.value<std::uint8_t>(with_anchor_);
    out.value<std::uint8_t>(with_master_);
    out.value<std::uint64_t>(num_rows_);
    out.value<std::uint64_t>(resident_pages());
    std::vector<float> floats(kRowsPerPage * floats_per_row_);
    std::vector<std::uint32_t> counters(kRowsPerPage * kCounters);
    for (std::size_t i = 0; i < pages_.size(); ++i) {
        const Page* page = pages_[i].load();
        if (!page) continue;
        out.value<std::uint64_t>(i);
        out.value<std::uint32_t>(page->last_scan.load());
        // The file keeps the page's floats and then its counters, each in row order.
        for (std::size_t slot = 0; slot < kRowsPerPage; ++slot) {
            std::copy_n(floats_at(*page, slot), floats_per_row_,
                        floats.begin() + std::ptrdiff_t(slot * floats_per_row_));
            std::copy_n(counters_at(*page, slot), kCounters,
                        counters.begin() + std::ptrdiff_t(slot * kCounters));
        }
        out.array(floats);
        out.array(counters);
    }
}

void FeatureRowState::load(BinaryReader& in) {
    in.expect_tag("feature row state");
    const auto dim = in.value<std::int32_t>("row state feature size");
    const bool anchor = in.value<std::uint8_t>("row state anchor flag") != 0;
    const bool master = in.value<std::uint8_t>("row state master flag") != 0;
    if (dim != dim_ || anchor != with_anchor_ || master != with_master_) {
        in.fail("row state layout", "(feature size " + std::to_string(dim) + ", anchors " +
                                        std::to_string(anchor) + ", master copy " +
                                        std::to_string(master) + ") differs from this run's");
    }
    const auto rows = in.value<std::uint64_t>("row count");
    if (rows != num_rows_) {
        in.fail("row count",
                std::to_string(rows) + " differs from the map's " + std::to_string(num_rows_));
    }
    const auto count = in.value<std::uint64_t>("page count");
    if (count > pages_.size()) in.fail("page count", "exceeds the page table");
    for (std::size_t i = 0; i < pages_.size(); ++i) drop_page(i);
    std::vector<float> floats(kRowsPerPage * floats_per_row_);
    std::vector<std::uint32_t> counters(kRowsPerPage * kCounters);
    for (std::uint64_t k = 0; k < count; ++k) {
        const auto index = in.value<std::uint64_t>("page index");
        if (index >= pages_.size() || pages_[index].load()) {
            in.fail("page index", std::to_string(index) + " is out of range or repeated");
        }
        auto page = std::make_unique<Page>(page_storage(index));
        page->last_scan.store(in.value<std::uint32_t>("page scan"));
        in.array_into(floats.data(), floats.size(), "page values");
        in.array_into(counters.data(), counters.size(), "page counters");
        for (std::size_t slot = 0; slot < kRowsPerPage; ++slot) {
            std::copy_n(floats.begin() + std::ptrdiff_t(slot * floats_per_row_), floats_per_row_,
                        floats_at(*page, slot));
            std::copy_n(counters.begin() + std::ptrdiff_t(slot * kCounters), kCounters,
                        counters_at(*page, slot));
        }
        pages_[index].store(page.release());
    }
}

}  // namespace shine
