#include "shine/core/huge_page_region.hpp"

#include <sys/mman.h>

#include <cstdint>
#include <cstring>
#include <new>
#include <utility>

namespace shine {

HugePageRegion::HugePageRegion(std::size_t bytes) {
    if (bytes == 0) return;
    if (bytes > static_cast<std::size_t>(-1) / 2 - kHugePageBytes) throw std::bad_alloc();
    const std::size_t size = (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes;
    // Map one huge page more than needed and trim both ends to the 2 MiB boundary.
    const std::size_t mapped = size + kHugePageBytes;
    void* raw = mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw == MAP_FAILED) throw std::bad_alloc();
    const auto start = reinterpret_cast<std::uintptr_t>(raw);
    const std::uintptr_t aligned = (start + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
    const std::size_t head = aligned - start;
    const std::size_t tail = mapped - head - size;
    if (head > 0) munmap(raw, head);
    if (tail > 0) munmap(reinterpret_cast<void*>(aligned + size), tail);
    data_ = reinterpret_cast<void*>(aligned);
    bytes_ = size;
#if defined(MADV_HUGEPAGE)
    // Advice only: without THP in the kernel this fails and the region keeps small pages.
    madvise(data_, bytes_, MADV_HUGEPAGE);
#endif
}

HugePageRegion::~HugePageRegion() {
    if (data_) munmap(data_, bytes_);
}

HugePageRegion::HugePageRegion(HugePageRegion&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)), bytes_(std::exchange(other.bytes_, 0)) {}

HugePageRegion& HugePageRegion::operator=(HugePageRegion&& other) noexcept {
    if (this != &other) {
        if (data_) munmap(data_, bytes_);
        data_ = std::exchange(other.data_, nullptr);
        bytes_ = std::exchange(other.bytes_, 0);
    }
    return *this;
}

void HugePageRegion::discard(std::size_t offset, std::size_t bytes) {
    if (bytes == 0) return;
    void* start = static_cast<char*>(data_) + offset;
    // Private anonymous memory reads as zeros after MADV_DONTNEED; should the advice fail, the
    // zeros are written instead.
    if (madvise(start, bytes, MADV_DONTNEED) != 0) std::memset(start, 0, bytes);
}

}  // namespace shine
