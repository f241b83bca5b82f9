#include "csrbf/displacement_field.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace csrbf {

template <class T>
DisplacementField<T>::DisplacementField(const SpaceMap& map, const T* rest, std::size_t n)
    : rest_(rest, rest + 3 * n), d_(3 * n) {
  map.displacements(rest_.data(), d_.data(), n);
}

template <class T>
void DisplacementField<T>::update(const SpaceMap& map) {
  map.displacements(rest_.data(), d_.data(), size());
}

template <class T>
void DisplacementField<T>::apply(double phase, T* out) const {
  check_phase(phase);
  const T t = T(phase);
  const T* r = rest_.data();
  const T* d = d_.data();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rest_.size(), 1 << 15),
                    [&](const tbb::blocked_range<std::size_t>& b) {
                      for (std::size_t i = b.begin(); i < b.end(); ++i) out[i] = r[i] + t * d[i];
                    });
}

template class DisplacementField<float>;
template class DisplacementField<double>;

}  // namespace csrbf
