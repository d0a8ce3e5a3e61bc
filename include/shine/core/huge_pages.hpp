// Transparent huge pages for large, randomly accessed arrays.
//
// Training reads and writes feature rows, their optimiser state and their index in random order
// over tens of megabytes; with 4 KiB pages nearly every such access also misses the TLB. Linux
// backs a range with 2 MiB pages when it is marked with madvise(MADV_HUGEPAGE) (the default
// "madvise" mode of /sys/kernel/mm/transparent_hugepage/enabled), for the memory first touched
// after the call. This is a hint: on other systems, or when the kernel declines, nothing changes.
#pragma once

#include <cstddef>

namespace shine {

/// Bytes below which advise_huge_pages() does nothing: a range must hold an aligned 2 MiB page.
constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;

/// Asks the kernel to back the whole 2 MiB pages inside [data, data + bytes) with huge pages.
/// Never fails; a no-op for small ranges and where the call is unsupported.
void advise_huge_pages(void* data, std::size_t bytes);

}  // namespace shine
