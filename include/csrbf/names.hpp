// One name table per option enum: the names the command line, the JSON files, Python and the VTK
// adapter accept and print, written once. parse_name() takes any case and the aliases; name_of()
// gives the canonical name; names() and names_text() list them for help texts and error messages.
#pragma once

#include "csrbf/fit_options.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/ordering.hpp"

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace csrbf {

template <class E>
struct Name {
  E value;
  std::string_view name;   ///< canonical: printed, and written to JSON
  std::string_view alias;  ///< also accepted ("" for none)
};

/// Specialised for each enum with `static constexpr std::array<Name<E>, K> entries`.
template <class E>
struct NameTable;

template <>
struct NameTable<Kernel> {
  static constexpr std::array<Name<Kernel>, 4> entries{{{Kernel::C0, "c0", "psi20"},
                                                        {Kernel::C2, "c2", "psi31"},
                                                        {Kernel::C4, "c4", "psi42"},
                                                        {Kernel::C6, "c6", "psi53"}}};
};
template <>
struct NameTable<Polynomial> {
  static constexpr std::array<Name<Polynomial>, 3> entries{
      {{Polynomial::None, "none", ""}, {Polynomial::Constant, "constant", ""}, {Polynomial::Linear, "linear", ""}}};
};
template <>
struct NameTable<Solver> {
  static constexpr std::array<Name<Solver>, 5> entries{{{Solver::Auto, "auto", ""},
                                                        {Solver::Envelope, "envelope", ""},
                                                        {Solver::Eigen, "eigen", ""},
                                                        {Solver::Cholmod, "cholmod", ""},
                                                        {Solver::Cg, "cg", ""}}};
};
template <>
struct NameTable<Ordering> {
  static constexpr std::array<Name<Ordering>, 5> entries{
      {{Ordering::Auto, "auto", ""},
       {Ordering::BreadthFirst, "breadth-first", "bfs"},
       {Ordering::ReverseBreadthFirst, "reverse-breadth-first", "rbfs"},
       {Ordering::ReverseCuthillMcKee, "rcm", "reverse-cuthill-mckee"},
       {Ordering::Identity, "identity", "none"}}};
};

/// The canonical name of v ("?" for a value outside the table).
template <class E>
constexpr std::string_view name_of(E v) noexcept {
  for (const auto& e : NameTable<E>::entries)
    if (e.value == v) return e.name;
  return "?";
}

/// The position of v in its table (0 for a value outside it): for combo boxes and integer constants.
template <class E>
constexpr std::size_t table_index(E v) noexcept {
  for (std::size_t i = 0; i < NameTable<E>::entries.size(); ++i)
    if (NameTable<E>::entries[i].value == v) return i;
  return 0;
}

/// The value named `text`, in any case, by its name or alias.
template <class E>
std::optional<E> parse_name(std::string_view text) noexcept {
  const auto same = [text](std::string_view name) {
    if (name.empty() || name.size() != text.size()) return false;
    for (std::size_t i = 0; i < name.size(); ++i) {
      char c = text[i];
      if (c >= 'A' && c <= 'Z') c = char(c - 'A' + 'a');
      if (c != name[i]) return false;
    }
    return true;
  };
  for (const auto& e : NameTable<E>::entries)
    if (same(e.name) || same(e.alias)) return e.value;
  return std::nullopt;
}

/// The canonical names, in table order (for CLI11's IsMember, combo boxes, help texts).
template <class E>
std::vector<std::string> names() {
  std::vector<std::string> out;
  for (const auto& e : NameTable<E>::entries) out.emplace_back(e.name);
  return out;
}

/// "'c0', 'c2', 'c4' or 'c6'", each name in `quote`s, for error messages.
template <class E>
std::string names_text(std::string_view quote = "'") {
  std::string out;
  const auto& t = NameTable<E>::entries;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (i > 0) out += i + 1 == t.size() ? " or " : ", ";
    out += std::string(quote) + std::string(t[i].name) + std::string(quote);
  }
  return out;
}

}  // namespace csrbf
