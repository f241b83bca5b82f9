// The Picker's undo step, a whole state before and after: pushed by the window's edits and by the
// end of a drag in the view.
#pragma once

#include "picker_window.hpp"

#include <QUndoCommand>

#include <utility>

namespace csrbf::picker {

/// One edit: the state before and after. The first redo() is the edit itself, already applied.
class StateCommand : public QUndoCommand {
 public:
  StateCommand(PickerWindow* w, State before, State after, const QString& text, int merge_id)
      : QUndoCommand(text), w_(w), before_(std::move(before)), after_(std::move(after)), merge_id_(merge_id) {}
  void undo() override { w_->restore(before_); }
  void redo() override {
    if (first_) {
      first_ = false;
      return;
    }
    w_->restore(after_);
  }
  int id() const override { return merge_id_; }
  bool mergeWith(const QUndoCommand* other) override {
    const auto* o = static_cast<const StateCommand*>(other);
    after_ = o->after_;
    return true;
  }

 private:
  PickerWindow* w_;
  State before_, after_;
  int merge_id_;
  bool first_ = true;
};

}  // namespace csrbf::picker
