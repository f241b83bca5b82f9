// The Composer's undo step, the scene's JSON before and after: pushed by the window's edits and by
// the end of a key drag in the view.
#pragma once

#include "composer_window.hpp"

#include <QUndoCommand>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <utility>

namespace csrbf::composer {

/// One edit: the scene JSON before and after; the first redo() is the edit itself.
class JsonCommand : public QUndoCommand {
 public:
  /// `base`: the folder the two states' relative paths were written for (the document's then).
  JsonCommand(ComposerWindow* w, nlohmann::json before, nlohmann::json after, std::filesystem::path base,
              const QString& text)
      : QUndoCommand(text), w_(w), before_(std::move(before)), after_(std::move(after)), base_(std::move(base)) {}
  void undo() override { w_->restore(before_, base_); }
  void redo() override {
    if (first_) {
      first_ = false;
      return;
    }
    w_->restore(after_, base_);
  }

 private:
  ComposerWindow* w_;
  nlohmann::json before_, after_;
  std::filesystem::path base_;
  bool first_ = true;
};

}  // namespace csrbf::composer
