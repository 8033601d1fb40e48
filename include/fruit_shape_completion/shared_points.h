#pragma once
// An immutable point list that copies of its owner share. A fruit estimate is copied whenever it
// is carried to the next update, handed out in a result snapshot or kept by a host; with its
// points (hundreds per fruit) copied each time, every update would cost in proportion to every
// fruit mapped. Reads look like a const PointList; a write replaces the whole list.
#include <fruit_shape_completion/types.h>

#include <memory>
#include <utility>

namespace fruit_shape_completion {

class SharedPoints {
 public:
  SharedPoints() = default;
  SharedPoints(PointList points)  // NOLINT: implicit, as assigning a PointList
      : points_(points.empty() ? nullptr : std::make_shared<const PointList>(std::move(points))) {}
  SharedPoints& operator=(PointList points) { return *this = SharedPoints(std::move(points)); }

  const PointList& get() const { return points_ ? *points_ : none(); }
  operator const PointList&() const { return get(); }  // NOLINT: passes where a PointList is read

  std::size_t size() const { return get().size(); }
  bool empty() const { return get().empty(); }
  const Point& operator[](std::size_t i) const { return get()[i]; }
  const Point& front() const { return get().front(); }
  const Point& back() const { return get().back(); }
  PointList::const_iterator begin() const { return get().begin(); }
  PointList::const_iterator end() const { return get().end(); }
  const Point* data() const { return get().data(); }
  void clear() { points_.reset(); }
  // Whether both share one list (no copy was made).
  bool sharesWith(const SharedPoints& other) const { return points_ == other.points_; }

 private:
  static const PointList& none() {
    static const PointList kEmpty;
    return kEmpty;
  }
  std::shared_ptr<const PointList> points_;
};

}  // namespace fruit_shape_completion
