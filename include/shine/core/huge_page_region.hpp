// Zero-filled anonymous memory that the kernel may back with transparent huge pages.
//
// The optimiser's row state is read in random row order, a few cache lines per row, over tens of
// megabytes: with 4 KiB pages nearly every access also misses the TLB. A region here is its own
// mapping, aligned to 2 MiB and marked with madvise(MADV_HUGEPAGE), so it gets huge pages also
// where the system's THP setting is `madvise` (Debian's default). Marking the whole mapping, and
// nothing but it, keeps the madvise from splitting a mapping that someone else grows (see
// TrivialArray). Nothing is resident until it is touched.
#pragma once

#include <cstddef>

namespace shine {

class HugePageRegion {
  public:
    static constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;

    HugePageRegion() = default;
    /// At least `bytes` (rounded up to whole huge pages), all zero. Throws std::bad_alloc.
    explicit HugePageRegion(std::size_t bytes);
    ~HugePageRegion();
    HugePageRegion(HugePageRegion&& other) noexcept;
    HugePageRegion& operator=(HugePageRegion&& other) noexcept;
    HugePageRegion(const HugePageRegion&) = delete;
    HugePageRegion& operator=(const HugePageRegion&) = delete;

    void* data() const { return data_; }
    std::size_t bytes() const { return bytes_; }
    /// Hands the memory of [offset, offset + bytes) back to the system; it reads as zeros again.
    /// Both must be multiples of the system page size.
    void discard(std::size_t offset, std::size_t bytes);

  private:
    void* data_ = nullptr;
    std::size_t bytes_ = 0;
};

}  // namespace shine
