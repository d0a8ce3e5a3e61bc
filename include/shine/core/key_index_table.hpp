// A map from 64-bit keys (packed voxel coordinates and the like) to dense indices 0, 1, 2, ... in
// the order the keys were first inserted, so that per-key values live in plain vectors beside it.
// An open-addressing table: Fibonacci hashing (the product's top bits depend on all of the
// key's), linear probing, grown to twice its length before it is half full.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace shine {

class KeyIndexTable {
  public:
    /// The one key that cannot be stored: it marks an empty slot.
    static constexpr std::uint64_t kNoKey = ~std::uint64_t{0};

    KeyIndexTable() { slots_.assign(std::size_t{1} << bits_, Slot{}); }

    /// Keys stored (the next new key's index).
    std::size_t size() const { return size_; }
    bool empty() const { return size_ == 0; }

    /// The index of `key`, or -1 if it is not stored.
    std::int64_t find(std::uint64_t key) const {
        const std::size_t mask = slots_.size() - 1;
        for (std::size_t at = slot_of(key);; at = (at + 1) & mask) {
            if (slots_[at].key == key) return slots_[at].index;
            if (slots_[at].key == kNoKey) return -1;
        }
    }

    /// The index of `key` (not kNoKey), stored now with the next index if it was not there;
    /// `inserted` (if given) says whether it was.
    std::uint32_t find_or_insert(std::uint64_t key, bool* inserted = nullptr) {
        if (2 * (size_ + 1) > slots_.size()) grow();
        const std::size_t mask = slots_.size() - 1;
        std::size_t at = slot_of(key);
        for (; slots_[at].key != kNoKey; at = (at + 1) & mask) {
            if (slots_[at].key == key) {
                if (inserted) *inserted = false;
                return slots_[at].index;
            }
        }
        slots_[at] = {key, static_cast<std::uint32_t>(size_++)};
        if (inserted) *inserted = true;
        return slots_[at].index;
    }

  private:
    struct Slot {
        std::uint64_t key = kNoKey;
        std::uint32_t index = 0;
    };

    std::size_t slot_of(std::uint64_t key) const {
        return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits_));
    }

    void grow() {
        std::vector<Slot> old(slots_.size() * 2, Slot{});
        old.swap(slots_);
        ++bits_;
        const std::size_t mask = slots_.size() - 1;
        for (const Slot& slot : old) {
            if (slot.key == kNoKey) continue;
            std::size_t at = slot_of(slot.key);
            while (slots_[at].key != kNoKey) at = (at + 1) & mask;
            slots_[at] = slot;
        }
    }

    std::vector<Slot> slots_;
    int bits_ = 10;  ///< log2(slots_.size())
    std::size_t size_ = 0;
};

}  // namespace shine
