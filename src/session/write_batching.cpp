#include "session/write_batching.hpp"

#include <utility>

namespace loopwire::session {
namespace {

thread_local WriteBatching::Scope* current_scope = nullptr;

}  // namespace

WriteBatching::Scope::Scope(Post post) : post_(std::move(post)), outer_(current_scope) { current_scope = this; }

WriteBatching::Scope::~Scope() { current_scope = outer_; }

void WriteBatching::Scope::run_flushes() {
    posted_ = false;
    // A flush may send (and defer) again: that starts the next round's list.
    auto flushes = std::exchange(flushes_, {});
    for (auto& flush : flushes) flush();
}

bool WriteBatching::defer(std::function<void()> flush) {
    Scope* scope = current_scope;
    if (scope == nullptr) return false;
    scope->flushes_.push_back(std::move(flush));
    if (!scope->posted_) {
        scope->posted_ = true;
        // The scope lives as long as the loop runs on this thread, which is where this runs.
        scope->post_([scope] { scope->run_flushes(); });
    }
    return true;
}

}  // namespace loopwire::session
