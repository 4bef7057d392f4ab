#pragma once
// IdSet: a set of tet or vertex ids, a std::unordered_set whose nodes come from a free list
// kept per thread instead of one malloc and one free each.
//
// The cut and improvement passes build and drop such sets many times per cut step (what was
// seen, queued, frozen, stuck), and several of them iterate a set (an improvement pass queues
// its region in the set's order), so the meshes they make depend on that order. A different
// container would change it; a different allocator does not: the hash table's layout and
// order follow only from the keys, the insertions and the bucket counts. docs/cut.md (step
// time) has what the nodes cost.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <new>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#define INCISE_ID_SET_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define INCISE_ID_SET_ASAN 1
#endif
#endif
#ifdef INCISE_ID_SET_ASAN
#include <sanitizer/asan_interface.h>  // a node waiting in the pool is poisoned: a use after free still shows
#define INCISE_ID_SET_POISON(p, n) ASAN_POISON_MEMORY_REGION(p, n)
#define INCISE_ID_SET_UNPOISON(p, n) ASAN_UNPOISON_MEMORY_REGION(p, n)
#else
#define INCISE_ID_SET_POISON(p, n) ((void)(p), (void)(n))
#define INCISE_ID_SET_UNPOISON(p, n) ((void)(p), (void)(n))
#endif

namespace incise {

namespace id_set_detail {

// Blocks of one size, recycled on the thread that frees them. At most kKeep are kept; the rest
// go back to the heap, so a pass that once held a large set does not pin its memory.
template <std::size_t Size>
class NodePool {
public:
  static constexpr std::size_t kKeep = 1 << 16;
  void* take() {
    if (free_.empty()) return ::operator new(Size);
    void* p = free_.back();
    free_.pop_back();
    INCISE_ID_SET_UNPOISON(p, Size);
    return p;
  }
  void give(void* p) noexcept {
    if (free_.size() >= kKeep) {
      ::operator delete(p);
      return;
    }
    try {
      free_.push_back(p);
    } catch (...) {  // no room to remember it: back to the heap
      ::operator delete(p);
      return;
    }
    INCISE_ID_SET_POISON(p, Size);
  }
  ~NodePool();

private:
  std::vector<void*> free_;
};

// Set once the thread's pool is gone (a set destroyed after it, by another thread-local's
// destructor, frees to the heap). Trivially destructible, so it stays readable until the
// thread's storage goes.
template <std::size_t Size>
inline thread_local bool pool_closed = false;

template <std::size_t Size>
NodePool<Size>::~NodePool() {
  for (void* p : free_) {
    INCISE_ID_SET_UNPOISON(p, Size);
    ::operator delete(p);
  }
  free_.clear();
  pool_closed<Size> = true;
}

template <std::size_t Size>
NodePool<Size>& pool() {
  thread_local NodePool<Size> p;
  return p;
}

}  // namespace id_set_detail

// Single objects (hash nodes) from the thread's pool; arrays (bucket tables) from the heap.
// Stateless: any two compare equal, so containers swap and move as with std::allocator.
template <class T>
struct NodePoolAllocator {
  using value_type = T;
  static_assert(alignof(T) <= __STDCPP_DEFAULT_NEW_ALIGNMENT__);
  NodePoolAllocator() noexcept = default;
  template <class U>
  NodePoolAllocator(const NodePoolAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) {
    if (n == 1 && !id_set_detail::pool_closed<sizeof(T)>)
      return static_cast<T*>(id_set_detail::pool<sizeof(T)>().take());
    return static_cast<T*>(::operator new(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (n == 1 && !id_set_detail::pool_closed<sizeof(T)>) id_set_detail::pool<sizeof(T)>().give(p);
    else ::operator delete(p);
  }
  template <class U>
  bool operator==(const NodePoolAllocator<U>&) const noexcept {
    return true;
  }
};

using IdSet = std::unordered_set<std::uint32_t, std::hash<std::uint32_t>, std::equal_to<std::uint32_t>,
                                 NodePoolAllocator<std::uint32_t>>;

template <class V>
using IdMap = std::unordered_map<std::uint32_t, V, std::hash<std::uint32_t>, std::equal_to<std::uint32_t>,
                                 NodePoolAllocator<std::pair<const std::uint32_t, V>>>;

}  // namespace incise
