// Private: the particle filter's column storage (used by pf_impl.hpp only).
#pragma once

#include <algorithm>
#include <cstddef>
#include <new>
#include <vector>

namespace safenav {

/// Columns of doubles for the particle filter, each starting on a 64-byte
/// boundary (the column stride is padded to 8 doubles): vector loads then
/// never split a cache line, whichever allocator the host process uses.
class Columns {
 public:
  void resize(int rows, int cols) {
    stride_ = (rows + 7) / 8 * 8;
    data_.assign(static_cast<std::size_t>(stride_) * cols, 0.0);
  }
  int stride() const { return stride_; }
  double* col(int c) { return data_.data() + static_cast<std::ptrdiff_t>(c) * stride_; }
  const double* col(int c) const { return data_.data() + static_cast<std::ptrdiff_t>(c) * stride_; }
  void swap(Columns& o) noexcept {
    data_.swap(o.data_);
    std::swap(stride_, o.stride_);
  }

 private:
  template <class T>
  struct Allocator {
    using value_type = T;
    Allocator() = default;
    template <class U>
    Allocator(const Allocator<U>&) noexcept {}
    T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t{64})); }
    void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t{64}); }
    friend bool operator==(const Allocator&, const Allocator&) { return true; }
    friend bool operator!=(const Allocator&, const Allocator&) { return false; }
  };
  std::vector<double, Allocator<double>> data_;
  int stride_ = 0;
};

}  // namespace safenav
