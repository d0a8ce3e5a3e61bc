// libFuzzer target: .vdb files, as `shine bake/mesh` (map.vdb) and the surface readers
// (surface.vdb) load them: the structure check first, then OpenVDB through the loaders.
//
// OpenVDB only reads from paths, so every input goes through a scratch file. Set
// SHINE_FUZZ_VDB_SKIP_CHECK=1 to hand inputs to OpenVDB without the structure check (to see what
// the check protects against).
#include <stdlib.h>

#include <cstddef>
#include <cstdlib>
#include <new>

#include "fuzz_common.hpp"
#include "shine/bake/level_set_file.hpp"
#include "shine/io/vdb_file_check.hpp"
#include "shine/model/map_file.hpp"

// OpenVDB trusts the compressed sizes inside voxel data and allocates what they say (up to
// 2^63 bytes). In a release build such a request throws std::bad_alloc, which the loaders report
// as an IoError ("not a valid .vdb file (std::bad_alloc)"); AddressSanitizer instead aborts on
// any allocation it cannot serve. These operators restore the release behaviour for requests
// above kMaxAllocationBytes, so that the fuzzer looks for crashes, not for OpenVDB's trust.
namespace {
constexpr std::size_t kMaxAllocationBytes = std::size_t{1} << 30;  // 1 GiB

void* allocate(std::size_t n, std::size_t alignment = alignof(std::max_align_t)) {
    if (n > kMaxAllocationBytes) return nullptr;
    void* p = nullptr;
    if (alignment <= alignof(std::max_align_t)) return std::malloc(n == 0 ? 1 : n);
    return ::posix_memalign(&p, alignment, n == 0 ? 1 : n) == 0 ? p : nullptr;
}

void* allocate_or_throw(std::size_t n, std::size_t alignment = alignof(std::max_align_t)) {
    if (void* p = allocate(n, alignment)) return p;
    throw std::bad_alloc();
}
}  // namespace

// Every form of the global operators, so that new and delete always pair malloc with free.
void* operator new(std::size_t n) { return allocate_or_throw(n); }
void* operator new[](std::size_t n) { return allocate_or_throw(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new(std::size_t n, std::align_val_t a) {
    return allocate_or_throw(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
    return allocate_or_throw(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
    return allocate(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
    return allocate(n, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
    std::free(p);
}

namespace {
const bool kSkipCheck = [] {
    const char* v = std::getenv("SHINE_FUZZ_VDB_SKIP_CHECK");
    return v != nullptr && std::string(v) == "1";
}();
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    // The scratch file's name must appear in messages instead of kSource.
    static shine_fuzz::ScratchFile scratch(".vdb");
    const std::filesystem::path& path = scratch.write(shine_fuzz::as_view(data, size));
    const auto check_names_file = [&](const shine::Error& e) {
        if (std::string(e.what()).find(path.filename().string()) == std::string::npos) {
            std::fprintf(stderr, "error message does not name the file: %s\n", e.what());
            std::abort();
        }
    };
    if (!kSkipCheck) {
        try {
            shine::check_vdb_file(path);
        } catch (const shine::Error& e) {
            check_names_file(e);
            return 0;
        }
    }
    try {
        shine::load_neural_map(path);
    } catch (const shine::Error& e) {
        check_names_file(e);
    }
    try {
        shine::read_level_set(path);
    } catch (const shine::Error& e) {
        check_names_file(e);
    }
    return 0;
}
