// The value types every layer of csrbf shares: a point, a row-major matrix of right-hand sides, and
// a compact list of polygons.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <new>
#include <span>
#include <vector>

namespace csrbf {

/// A point or a displacement in 3-D.
using Vec3 = Eigen::Vector3d;
/// N x m, one row per control point: the right-hand sides of the solves, a row's values together.
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// An allocator whose resize() leaves new elements uninitialised (value-initialises nothing): a
/// large array that a parallel pass fills completely is then not written twice, and its pages are
/// first touched by the threads that fill them rather than by one memset (on virtual machines page
/// faults dominate: 0.5 s of a 1e6-control fit). Elements constructed with arguments are constructed.
namespace detail {
/// Arrays of at least kHugePageArray bytes are placed on 2 MiB boundaries and marked for transparent
/// huge pages (madvise): one page fault where there were 512 (1e5 scattered points: page faults were
/// 16% of an interpolator's fit, 10% after).
inline constexpr std::size_t kHugePageArray = std::size_t(4) << 20;
void* allocate_huge(std::size_t bytes);
void free_huge(void* p) noexcept;
}  // namespace detail

template <class T>
struct UninitializedAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <class U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    if (n * sizeof(T) >= detail::kHugePageArray) return static_cast<T*>(detail::allocate_huge(n * sizeof(T)));
    return std::allocator<T>::allocate(n);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) >= detail::kHugePageArray) return detail::free_huge(p);
    std::allocator<T>::deallocate(p, n);
  }
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
/// A vector of trivial values whose resize() does not zero them (UninitializedAllocator).
template <class T>
using FillVector = std::vector<T, UninitializedAllocator<T>>;

/// Polygons (a mesh's faces) in two flat arrays: polygon k holds the vertex indices
/// indices()[offsets()[k] .. offsets()[k + 1]). One allocation for a whole mesh, where a vector per
/// face made one per face.
class PolygonList {
 public:
  PolygonList() = default;
  PolygonList(std::initializer_list<std::initializer_list<std::uint32_t>> polygons) {
    for (const auto& p : polygons) push_back(std::span<const std::uint32_t>(p.begin(), p.size()));
  }

  std::size_t size() const noexcept { return offsets_.size() - 1; }
  bool empty() const noexcept { return size() == 0; }
  /// The vertex indices of polygon k.
  std::span<const std::uint32_t> operator[](std::size_t k) const noexcept {
    return {indices_.data() + offsets_[k], offsets_[k + 1] - offsets_[k]};
  }
  std::span<std::uint32_t> operator[](std::size_t k) noexcept {
    return {indices_.data() + offsets_[k], offsets_[k + 1] - offsets_[k]};
  }
  void push_back(std::span<const std::uint32_t> polygon) {
    indices_.insert(indices_.end(), polygon.begin(), polygon.end());
    offsets_.push_back(indices_.size());
  }
  void push_back(std::initializer_list<std::uint32_t> polygon) {
    push_back(std::span<const std::uint32_t>(polygon.begin(), polygon.size()));
  }
  void reserve(std::size_t polygons, std::size_t indices) {
    offsets_.reserve(polygons + 1);
    indices_.reserve(indices);
  }
  void clear() noexcept {
    offsets_.assign(1, 0);
    indices_.clear();
  }
  /// Every polygon's indices, one after another.
  std::span<const std::uint32_t> indices() const noexcept { return indices_; }
  std::span<const std::size_t> offsets() const noexcept { return offsets_; }
  bool operator==(const PolygonList&) const = default;

  class Iterator {
   public:
    Iterator(const PolygonList* list, std::size_t k) : list_(list), k_(k) {}
    std::span<const std::uint32_t> operator*() const noexcept { return (*list_)[k_]; }
    Iterator& operator++() noexcept {
      ++k_;
      return *this;
    }
    bool operator==(const Iterator& o) const noexcept { return k_ == o.k_; }

   private:
    const PolygonList* list_;
    std::size_t k_;
  };
  Iterator begin() const noexcept { return {this, 0}; }
  Iterator end() const noexcept { return {this, size()}; }

 private:
  std::vector<std::size_t> offsets_{0};
  std::vector<std::uint32_t> indices_;
};

}  // namespace csrbf
