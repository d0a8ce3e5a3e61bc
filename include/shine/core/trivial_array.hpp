// A contiguous array of trivially copyable values, sized exactly, that grows in place.
//
// std::vector grows by allocating the new size and copying: for a feature table of hundreds of
// megabytes that gains a few rows with every scan, that is a full copy per scan and, for a moment,
// the table twice. This array grows with realloc instead: glibc serves blocks this large with
// mmap and grows them with mremap, which moves page-table entries rather than bytes, so growth
// costs neither the copy nor the second table. (Nothing may split the block's mapping: an
// madvise() on part of it, for transparent huge pages, made every later growth a full copy,
// because mremap() moves only whole mappings; docs/performance.md.)
#pragma once

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <new>
#include <type_traits>
#include <utility>

namespace shine {

template <typename T>
class TrivialArray {
    static_assert(std::is_trivially_copyable_v<T>, "TrivialArray holds trivially copyable values");

  public:
    TrivialArray() = default;
    /// Copies [first, last), converting each value to T.
    template <typename It>
    TrivialArray(It first, It last) {
        resize(static_cast<std::size_t>(last - first));
        for (std::size_t i = 0; first != last; ++first, ++i) data_[i] = static_cast<T>(*first);
    }
    TrivialArray(const TrivialArray& other) {
        resize(other.size_);
        if (size_ > 0) std::memcpy(data_, other.data_, size_ * sizeof(T));
    }
    TrivialArray(TrivialArray&& other) noexcept
        : data_(std::exchange(other.data_, nullptr)), size_(std::exchange(other.size_, 0)) {}
    TrivialArray& operator=(TrivialArray other) noexcept {
        std::swap(data_, other.data_);
        std::swap(size_, other.size_);
        return *this;
    }
    ~TrivialArray() { std::free(data_); }

    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }
    /// Bytes held: the array is sized exactly.
    std::size_t bytes() const { return size_ * sizeof(T); }
    T* data() { return data_; }
    const T* data() const { return data_; }
    T& operator[](std::size_t i) { return data_[i]; }
    const T& operator[](std::size_t i) const { return data_[i]; }
    T* begin() { return data_; }
    T* end() { return data_ + size_; }
    const T* begin() const { return data_; }
    const T* end() const { return data_ + size_; }

    /// Resizes to exactly `n` values; new values are `fill`. Existing values keep their contents
    /// (the block may move). Throws std::bad_alloc when memory runs out.
    void resize(std::size_t n, T fill = T()) {
        if (n == size_) return;
        if (n == 0) {
            std::free(data_);
            data_ = nullptr;
            size_ = 0;
            return;
        }
        if (n > static_cast<std::size_t>(-1) / sizeof(T)) throw std::bad_alloc();
        void* grown = std::realloc(data_, n * sizeof(T));
        if (!grown) throw std::bad_alloc();
        data_ = static_cast<T*>(grown);
        for (std::size_t i = size_; i < n; ++i) data_[i] = fill;
        size_ = n;
    }

  private:
    T* data_ = nullptr;
    std::size_t size_ = 0;
};

}  // namespace shine
