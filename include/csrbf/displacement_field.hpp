// Per-vertex displacements of one mesh under one SpaceMap, kept so that a new phase t costs one pass
// over memory: out = rest + t * d (the paper's section 4.4 phase parameter, for in-between frames).
#pragma once

#include "csrbf/space_map.hpp"

#include <span>
#include <vector>

namespace csrbf {

/// T is float (game meshes) or double. Holds its own copy of the rest positions and of d, both
/// interleaved n x 3. Not copyable by accident (use clone()); const members are thread-safe.
template <class T>
class DisplacementField {
 public:
  /// rest: n interleaved points (n x 3); copied.
  DisplacementField(const SpaceMap& map, const T* rest, std::size_t n);
  DisplacementField(DisplacementField&&) noexcept = default;
  DisplacementField& operator=(DisplacementField&&) noexcept = default;
  DisplacementField(const DisplacementField&) = delete;
  DisplacementField& operator=(const DisplacementField&) = delete;
  DisplacementField clone() const { return DisplacementField(*this, 0); }

  /// Recomputes d for another map (e.g. SpaceMap::with_destinations) over the same rest positions.
  void update(const SpaceMap& map);

  /// out (n x 3) = rest + phase * d. One pass; out must not alias the field's own buffers.
  void apply(double phase, T* out) const;

  std::size_t size() const noexcept { return rest_.size() / 3; }
  std::span<const T> rest() const noexcept { return rest_; }
  std::span<const T> displacements() const noexcept { return d_; }

 private:
  DisplacementField(const DisplacementField& o, int) : rest_(o.rest_), d_(o.d_) {}
  std::vector<T> rest_, d_;
};

extern template class DisplacementField<float>;
extern template class DisplacementField<double>;

}  // namespace csrbf
