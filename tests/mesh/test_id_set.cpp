// IdSet and IdMap: the same contents and the same iteration order as std::unordered_set and
// std::unordered_map under any sequence of edits (the cut and the improvement iterate them,
// and their meshes depend on that order), on any thread.
#include <catch2/catch.hpp>

#include <random>
#include <type_traits>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "mesh/id_set.h"

using namespace incise;

namespace {

template <class A, class B>
std::vector<std::uint32_t> keys_in_order(const A& a) {
  std::vector<std::uint32_t> out;
  for (const auto& x : a) {
    if constexpr (std::is_same_v<B, void>) out.push_back(x);
    else out.push_back(x.first);
  }
  return out;
}

}  // namespace

TEST_CASE("IdSet and IdMap iterate as the standard containers do, through inserts, erases, rehashes and clears", "[mesh][idset]") {
  std::mt19937 rng(2026);
  IdSet ours;
  std::unordered_set<std::uint32_t> theirs;
  IdMap<double> our_map;
  std::unordered_map<std::uint32_t, double> their_map;
  for (int round = 0; round < 20; ++round) {
    const std::uint32_t range = round % 2 ? 50 : 20000;  // few keys (collisions) and many (rehashes)
    const int edits = int(rng() % 5000);
    for (int e = 0; e < edits; ++e) {
      const std::uint32_t k = rng() % range;
      if (rng() % 3 == 0) {
        REQUIRE(ours.erase(k) == theirs.erase(k));
        REQUIRE(our_map.erase(k) == their_map.erase(k));
      } else {
        REQUIRE(ours.insert(k).second == theirs.insert(k).second);
        our_map[k] += double(e);
        their_map[k] += double(e);
      }
    }
    REQUIRE(ours.bucket_count() == theirs.bucket_count());
    REQUIRE(keys_in_order<IdSet, void>(ours) == keys_in_order<std::unordered_set<std::uint32_t>, void>(theirs));
    REQUIRE(keys_in_order<IdMap<double>, int>(our_map) ==
            keys_in_order<std::unordered_map<std::uint32_t, double>, int>(their_map));
    for (const auto& [k, v] : their_map) REQUIRE(our_map.at(k) == v);
    if (round % 7 == 6) {
      ours.clear();
      theirs.clear();
    }
    // Copies and moves keep the order too.
    IdSet copy(ours);
    REQUIRE(keys_in_order<IdSet, void>(copy) == keys_in_order<IdSet, void>(ours));
    IdSet moved(std::move(copy));
    REQUIRE(keys_in_order<IdSet, void>(moved) == keys_in_order<IdSet, void>(ours));
  }
}

TEST_CASE("IdSets built on one thread and destroyed on another, and on several threads at once, keep their ids", "[mesh][idset]") {
  std::vector<IdSet> built(4);
  std::vector<int> scratch_ok(built.size(), 1);  // Catch's assertions are not for other threads
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < built.size(); ++i)
    threads.emplace_back([&built, &scratch_ok, i] {
      for (int round = 0; round < 50; ++round) {
        IdSet scratch;
        for (std::uint32_t k = 0; k < 1000; ++k) scratch.insert(k * 7 + std::uint32_t(i));
        if (scratch.size() != 1000) scratch_ok[i] = 0;
      }
      for (std::uint32_t k = 0; k < 3000; ++k) built[i].insert(k * 3 + std::uint32_t(i));
    });
  for (auto& t : threads) t.join();
  for (int ok : scratch_ok) REQUIRE(ok == 1);
  for (std::size_t i = 0; i < built.size(); ++i) {
    REQUIRE(built[i].size() == 3000);
    for (std::uint32_t k = 0; k < 3000; ++k) REQUIRE(built[i].count(k * 3 + std::uint32_t(i)) == 1);
  }
  // Freed here, on the main thread, into its own pool: the main thread's next sets reuse them.
  built.clear();
  IdSet again;
  for (std::uint32_t k = 0; k < 5000; ++k) again.insert(k);
  REQUIRE(again.size() == 5000);
}
