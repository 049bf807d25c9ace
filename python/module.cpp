// The Python module `drape`: bindings of the engine's public API (engine/include/drape/) and
// of the scene loader (apps/drape/scene.h), nothing of its own. Names follow the C++ ones;
// definitions take keyword arguments; a sheet's state comes out as NumPy arrays that view
// the world's buffers (docs/python.md).
#include <drape/drape.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/operators.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cctype>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "run.h"
#include "scene.h"

namespace py = pybind11;

// Vec3 and Quat are plain tuples in Python: (x, y, z) and (w, x, y, z). Any sequence of
// numbers of the right length (a list, a NumPy array) is accepted where one is expected.
namespace pybind11::detail {

template <class T, std::size_t N>
struct tuple_value_caster {
  T value;
  bool load(handle src, bool) {
    if (!isinstance<sequence>(src) || isinstance<str>(src)) return false;
    const auto s = reinterpret_borrow<sequence>(src);
    if (s.size() != N) return false;
    double v[N];
    for (std::size_t k = 0; k < N; ++k) {
      make_caster<double> c;
      if (!c.load(s[k], true)) return false;
      v[k] = cast_op<double>(c);
    }
    if constexpr (N == 3) value = T{v[0], v[1], v[2]};
    else value = T{v[0], v[1], v[2], v[3]};
    return true;
  }
};

template <>
struct type_caster<drape::Vec3> : tuple_value_caster<drape::Vec3, 3> {
  static constexpr auto name = const_name("tuple[float, float, float]");
  template <class U>
  using cast_op_type = movable_cast_op_type<U>;
  operator drape::Vec3*() { return &value; }
  operator drape::Vec3&() { return value; }
  operator drape::Vec3&&() && { return std::move(value); }
  static handle cast(const drape::Vec3& v, return_value_policy, handle) { return make_tuple(v.x, v.y, v.z).release(); }
};

template <>
struct type_caster<drape::Quat> : tuple_value_caster<drape::Quat, 4> {
  static constexpr auto name = const_name("tuple[float, float, float, float]");
  template <class U>
  using cast_op_type = movable_cast_op_type<U>;
  operator drape::Quat*() { return &value; }
  operator drape::Quat&() { return value; }
  operator drape::Quat&&() && { return std::move(value); }
  static handle cast(const drape::Quat& q, return_value_policy, handle) {
    return make_tuple(q.w, q.x, q.y, q.z).release();
  }
};

}  // namespace pybind11::detail

namespace {

using namespace drape;

// An enum from its value or from its scene-format name: a name goes through the enum's own
// constructor, whose ValueError names what is unknown ("unknown integrator \"leapfrog\""),
// where pybind11's implicit conversion would report only "incompatible function arguments".
template <class E>
E enum_value(const py::object& value) {
  if (py::isinstance<py::str>(value)) return py::type::of<E>()(value).template cast<E>();
  try {
    return value.cast<E>();
  } catch (const py::cast_error&) {
    throw py::type_error(std::string("expected a ") + std::string(py::str(py::type::of<E>().attr("__name__"))) +
                         " or its name, got " + std::string(py::str(value.get_type().attr("__name__"))));
  }
}

// A repr listing the named attributes, Name(a=..., b=...), for definitions and results alike.
template <class Class>
void fields_repr(Class cls, std::shared_ptr<const std::vector<std::string>> names) {
  cls.def("__repr__", [names](py::object self) {
    std::string text = py::str(self.attr("__class__").attr("__name__"));
    text += "(";
    for (std::size_t k = 0; k < names->size(); ++k)
      text += (k ? ", " : "") + (*names)[k] + "=" + std::string(py::repr(self.attr((*names)[k].c_str())));
    return text + ")";
  });
}

// A result struct bound read-only, field by field, with the repr of its fields: each field
// is named once, as Fields names a definition's.
template <class T>
class Readout {
 public:
  explicit Readout(py::class_<T> cls) : cls_(std::move(cls)) {}
  template <class M>
  Readout& field(const char* name, const M T::*member) {
    cls_.def_readonly(name, member);
    names_->push_back(name);
    return *this;
  }
  template <class Getter>
  Readout& property(const char* name, Getter getter) {
    cls_.def_property_readonly(name, getter);
    names_->push_back(name);
    return *this;
  }
  py::class_<T>& done() {
    fields_repr(cls_, names_);
    return cls_;
  }

 private:
  py::class_<T> cls_;
  std::shared_ptr<std::vector<std::string>> names_ = std::make_shared<std::vector<std::string>>();
};

// A definition struct bound field by field: one line per field, and the class gets a
// constructor taking any of them as keyword arguments (an unknown name is a TypeError) and
// a repr listing them. A field added to SheetDef/WorldDef/ObstacleDef is one .field(...) line.
template <class T>
class Fields {
 public:
  Fields(py::module_& m, const char* name, const char* doc) : cls_(m, name, doc) {}

  template <class M>
  Fields& field(const char* name, M T::*member, const char* doc) {
    if constexpr (std::is_enum_v<M>) {
      cls_.def_property(
          name, [member](const T& self) { return self.*member; },
          [member](T& self, const py::object& value) { self.*member = enum_value<M>(value); }, doc);
    } else {
      cls_.def_readwrite(name, member, doc);
    }
    names_->push_back(name);
    return *this;
  }

  py::class_<T>& cls() { return cls_; }

  py::class_<T>& done() {
    auto names = names_;
    cls_.def(py::init([](const py::kwargs& kwargs) { return with_fields(T{}, kwargs); }),
             "Every field has a default; pass the ones to change as keyword arguments.");
    fields_repr(cls_, names);
    cls_.def("__copy__", [](const T& self) { return T(self); });
    cls_.def("__deepcopy__", [](const T& self, py::dict) { return T(self); });
    return cls_;
  }

  // `base` with the keyword arguments written into its fields, in the order given.
  static T with_fields(const T& base, const py::kwargs& kwargs) {
    py::object obj = py::cast(base);
    for (const auto& [key, value] : kwargs) {
      if (!py::hasattr(obj, key)) {
        throw py::type_error(std::string(py::str(obj.attr("__class__").attr("__name__"))) + " has no field '" +
                             std::string(py::str(key)) + "'");
      }
      obj.attr(key) = value;
    }
    return obj.cast<T>();
  }

 private:
  py::class_<T> cls_;
  std::shared_ptr<std::vector<std::string>> names_ = std::make_shared<std::vector<std::string>>();
};

// The Python name of an integrator from its row of the table: "semi_implicit_euler" →
// "SemiImplicitEuler"; a word with a digit is an acronym, all capitals ("rk4" → "RK4").
std::string python_name(std::string_view table_name) {
  std::string out;
  std::size_t begin = 0;
  while (begin <= table_name.size()) {
    std::size_t end = table_name.find('_', begin);
    if (end == std::string_view::npos) end = table_name.size();
    std::string word(table_name.substr(begin, end - begin));
    const bool acronym = std::any_of(word.begin(), word.end(), [](unsigned char c) { return std::isdigit(c); });
    for (std::size_t k = 0; k < word.size(); ++k)
      if (acronym || k == 0) word[k] = char(std::toupper(static_cast<unsigned char>(word[k])));
    out += word;
    begin = end + 1;
  }
  return out;
}

// An enum whose values the engine names (name(E(k)) for k = 0, 1, ... until "unknown"): each
// value under its name in CamelCase, a constructor from the scene format's name (ValueError
// naming an unknown one), `label` the name, and the name accepted wherever the enum is.
template <class E>
void bind_named_enum(py::module_& m, const char* cls, std::string_view (*name)(E), const std::string& what) {
  std::vector<E> values;
  for (int k = 0; name(E(k)) != "unknown"; ++k) values.push_back(E(k));
  py::enum_<E> e(m, cls);
  std::string names;
  for (E v : values) {
    e.value(python_name(name(v)).c_str(), v);
    names += (names.empty() ? "\"" : ", \"") + std::string(name(v)) + "\"";
  }
  e.def(py::init([values, name, what](const std::string& text) {
          for (E v : values)
            if (name(v) == text) return v;
          throw py::value_error("unknown " + what + " \"" + text + "\"");
        }),
        py::arg("name"), ("From the scene format's name: " + names).c_str())
      .def_property_readonly("label", [name](E v) { return std::string(name(v)); }, "the scene format's name");
  py::implicitly_convertible<std::string, E>();
}

// A definition from an optional object of its type and keyword arguments that change it.
template <class T>
T definition(const std::optional<T>& def, const py::kwargs& kwargs) {
  return Fields<T>::with_fields(def.value_or(T{}), kwargs);
}

// One sheet's six state arrays, each (m+1, n+1) in the grid's row-major order (eqs 2–3),
// viewing the world's buffers: no copy is made, and the world stays alive while they do.
struct SheetArrays {
  std::uint32_t m = 0, n = 0;
  py::array x, y, z, vx, vy, vz;
};

template <class Real, class Span>
py::array grid_array(const Span& span, std::uint32_t m, std::uint32_t n, py::handle owner, bool writeable) {
  py::array_t<Real> a({std::size_t(m) + 1, std::size_t(n) + 1}, {(std::size_t(n) + 1) * sizeof(Real), sizeof(Real)},
                      span.data(), owner);
  if (!writeable) a.attr("setflags")(py::arg("write") = false);
  return a;
}

template <class Real, class View>
SheetArrays arrays(const View& v, py::handle owner, bool writeable) {
  auto g = [&](const auto& s) { return grid_array<Real>(s, v.m, v.n, owner, writeable); };
  return {v.m, v.n, g(v.x), g(v.y), g(v.z), g(v.vx), g(v.vy), g(v.vz)};
}

// What the arrays of one sheet from view()/state() hold on to: the world, and from the
// sheet's removal on its buffers (remove_sheet hands them over while such arrays live), so
// an array of a removed sheet reads the sheet's last state, never freed memory.
struct SheetKeeper {
  py::object world;
  std::shared_ptr<const void> removed;
};

// The world's keepers, weakly, by (index, generation) of their sheet.
py::dict sheet_keepers(py::handle world) {
  return world.attr("__dict__").attr("setdefault")("_sheet_keepers", py::dict());
}

py::tuple keeper_key(SheetId id) { return py::make_tuple(id.index, id.generation); }

// The live keeper of the sheet's arrays (None if there is none).
py::object live_keeper(py::handle world, SheetId id) {
  const py::dict keepers = sheet_keepers(world);
  const py::tuple key = keeper_key(id);
  return keepers.contains(key) ? keepers[key]() : py::none();
}

// The keeper for new arrays of the sheet: the live one, else a new one.
py::object keeper_for(py::object world, SheetId id) {
  py::object keeper = live_keeper(world, id);
  if (!keeper.is_none()) return keeper;
  keeper = py::cast(SheetKeeper{world, nullptr});
  sheet_keepers(world)[keeper_key(id)] = py::module_::import("weakref").attr("ref")(keeper);
  return keeper;
}

template <class Real>
std::span<const Real> flat(const py::array_t<Real, py::array::c_style | py::array::forcecast>& a) {
  return {a.data(), std::size_t(a.size())};
}

// The World Python holds: the engine's world and a lock, so that calls on one world from
// several Python threads run one at a time instead of racing (a world stepped by two
// threads at once, or changed while another steps it, crashed the interpreter).
template <class Real>
struct PyWorld : BasicWorld<Real> {
  explicit PyWorld(BasicWorld<Real>&& world) : BasicWorld<Real>(std::move(world)) {}
  std::unique_ptr<std::recursive_mutex> lock = std::make_unique<std::recursive_mutex>();  // (movable)
};

// Holds a world's lock for one call, taken with the GIL held; waiting for it, the GIL is
// let go, so the thread that holds it can take the GIL back (run_frames' callbacks, a
// Motion's). Recursive: a run_frames callback may call its own world.
class Hold {
 public:
  template <class Real>
  explicit Hold(const PyWorld<Real>& world) : lock_(*world.lock, std::defer_lock) {
    if (lock_.try_lock()) return;
    const py::gil_scoped_release release;
    lock_.lock();
  }

 private:
  std::unique_lock<std::recursive_mutex> lock_;
};

// A method of the engine's world (or a lambda taking it first) as a method of PyWorld that
// holds the world's lock for the call; a reference it returns is copied under the lock.
template <class PW, class R, class C, class... A>
auto locked(R (C::*f)(A...)) {
  return [f](PW& self, A... a) -> std::decay_t<R> {
    const Hold hold(self);
    return (self.*f)(std::forward<A>(a)...);
  };
}
template <class PW, class R, class C, class... A>
auto locked(R (C::*f)(A...) const) {
  return [f](const PW& self, A... a) -> std::decay_t<R> {
    const Hold hold(self);
    return (self.*f)(std::forward<A>(a)...);
  };
}
template <class PW, class F, class R, class Self, class... A>
auto locked_call(F f, R (F::*)(Self, A...) const) {
  using World = std::conditional_t<std::is_const_v<std::remove_reference_t<Self>>, const PW&, PW&>;
  return [f](World self, A... a) -> std::decay_t<R> {
    const Hold hold(self);
    return f(self, std::forward<A>(a)...);
  };
}
template <class PW, class F>
auto locked(F f) {
  return locked_call<PW>(f, &F::operator());
}

template <class Real>
void bind_world(py::module_& m, const char* name, const char* doc) {
  using W = BasicWorld<Real>;
  using PW = PyWorld<Real>;
  using Array = py::array_t<Real, py::array::c_style | py::array::forcecast>;
  py::class_<PW> w(m, name, doc, py::dynamic_attr());  // __dict__ holds the sheets' keepers
  w.def(py::init([](std::optional<WorldDef> def, const py::kwargs& kwargs) { return PW(W(definition(def, kwargs))); }),
        py::arg("definition") = py::none(),
        "World(definition=None, **fields): a WorldDef, and/or WorldDef fields as keywords.");
  w.def("add_sheet",
        locked<PW>([](W& self, std::optional<SheetDef> def, const py::kwargs& kwargs) {
          return self.add_sheet(definition(def, kwargs));
        }),
        py::arg("definition") = py::none(),
        "Adds a sheet from a SheetDef and/or SheetDef fields as keywords. ValueError for a bad definition.");
  w.def(
      "remove_sheet",
      [](py::object self, SheetId id) {
        PW& world = self.cast<PW&>();
        const Hold hold(world);
        py::object keeper = live_keeper(self, id);
        if (keeper.is_none()) {
          world.remove_sheet(id);
        } else {  // its arrays live on: they keep its buffers, with its last state
          keeper.cast<SheetKeeper&>().removed = std::make_shared<RemovedSheet<Real>>(world.take_sheet(id));
        }
        const py::dict keepers = sheet_keepers(self);
        if (keepers.contains(keeper_key(id))) keepers.attr("pop")(keeper_key(id));
      },
      py::arg("sheet"), "Removes the sheet; arrays of it from view()/state() keep its last state.");
  w.def("add_obstacle",
        locked<PW>([](W& self, std::optional<ObstacleDef> def, const py::kwargs& kwargs) {
          const ObstacleDef d = definition(def, kwargs);
          // A Python motion that raises does so here, before the world takes a pool slot for it.
          if (d.motion && d.motion->kind == Motion::Kind::Callback && d.motion->callback) pose_at(*d.motion, self.time());
          return self.add_obstacle(d);
        }),
        py::arg("definition") = py::none(), "Adds an obstacle from an ObstacleDef and/or its fields as keywords.");
  w.def("remove_obstacle", locked<PW>(&W::remove_obstacle), py::arg("obstacle"));
  w.def("add_constraint",
        locked<PW>([](W& self, std::optional<ConstraintDef> def, const py::kwargs& kwargs) {
          return self.add_constraint(definition(def, kwargs));
        }),
        py::arg("definition") = py::none(),
        "Adds a constraint (paper 5.2) from a ConstraintDef and/or its fields as keywords. ValueError naming the "
        "field for a bad definition.");
  w.def("remove_constraint", locked<PW>(&W::remove_constraint), py::arg("constraint"));
  w.def("contains", locked<PW>(py::overload_cast<SheetId>(&W::contains, py::const_)), py::arg("sheet"));
  w.def("contains", locked<PW>(py::overload_cast<ObstacleId>(&W::contains, py::const_)), py::arg("obstacle"));
  w.def("contains", locked<PW>(py::overload_cast<ConstraintId>(&W::contains, py::const_)), py::arg("constraint"));
  w.def_property_readonly("sheet_count", locked<PW>(&W::sheet_count));
  w.def("__repr__", locked<PW>([name](W& self) {
          std::ostringstream out;
          out << "<drape." << name << ": " << self.sheet_count() << " sheet(s), " << self.obstacle_count()
              << " obstacle(s), t = " << self.time() << " s after " << self.step_count() << " substep(s) of "
              << integrator_name(self.def().integrator) << " at dt = " << self.def().dt << " s"
              << (self.halted() ? ", halted by the stability guard>" : ">");
          return out.str();
        }));
  w.def_property_readonly("obstacle_count", locked<PW>(&W::obstacle_count));
  w.def_property_readonly("constraint_count", locked<PW>(&W::constraint_count));
  w.def("sheets", locked<PW>(&W::sheets), "Sheet ids in the order they were added.");
  w.def("obstacles", locked<PW>(&W::obstacles), "Obstacle ids in the order they were added.");
  w.def("obstacle", locked<PW>(&W::obstacle), py::arg("obstacle"), "A copy of the obstacle's definition.");
  w.def("constraints", locked<PW>(&W::constraints), "Constraint ids in the order they were added.");
  w.def("constraint", locked<PW>(&W::constraint), py::arg("constraint"), "A copy of the constraint's definition.");

  w.def("view",
        [](py::object self, SheetId id) {
          const PW& world = self.cast<const PW&>();
          const Hold hold(world);
          const SheetView<Real> v = world.view(id);  // throws for a stale id
          return arrays<Real>(v, keeper_for(self, id), false);
        },
        py::arg("sheet"),
        "Read-only arrays x, y, z, vx, vy, vz of shape (m+1, n+1) over the sheet's buffers (no copy); they show "
        "every later step, and the sheet's last state once it is removed.");
  w.def("state",
        [](py::object self, SheetId id) {
          PW& world = self.cast<PW&>();
          const Hold hold(world);
          const SheetState<Real> v = world.state(id);
          return arrays<Real>(v, keeper_for(self, id), true);
        },
        py::arg("sheet"),
        "Writable arrays as view(); writes take effect at the next step (pinned points return to their pins).");
  w.def("set_state",
        locked<PW>([](W& self, SheetId id, const Array& x, const Array& y, const Array& z, const Array& vx,
                      const Array& vy, const Array& vz) {
          const SheetView<Real> v{0, 0, flat(x), flat(y), flat(z), flat(vx), flat(vy), flat(vz)};
          self.set_state(id, v);
        }),
        py::arg("sheet"), py::arg("x"), py::arg("y"), py::arg("z"), py::arg("vx"), py::arg("vy"), py::arg("vz"),
        "Copies positions and velocities (each holding the sheet's point count) into the sheet.");
  w.def("integrator_memory",
        locked<PW>([](const W& self, SheetId id) {
          const auto s = self.integrator_memory(id);
          return py::array_t<Real>(py::ssize_t(s.size()), s.data());  // a copy: the next step may move it
        }),
        py::arg("sheet"), "A copy of what the integrator carries between substeps for this sheet (checkpoints).");
  w.def("set_integrator_memory",
        locked<PW>([](W& self, SheetId id, const Array& memory) { self.set_integrator_memory(id, flat(memory)); }),
        py::arg("sheet"), py::arg("memory"));
  w.def("contact_memory", locked<PW>([](const W& self) {
    const std::vector<std::uint64_t> words = self.contact_memory();
    return py::array_t<std::uint64_t>(py::ssize_t(words.size()), words.data());
  }));
  w.def("set_contact_memory",
        locked<PW>([](W& self, const py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>& memory) {
          self.set_contact_memory(std::span<const std::uint64_t>(memory.data(), std::size_t(memory.size())));
        }),
        py::arg("memory"));

  // The GIL is released while the world steps, so Python threads can step several worlds
  // at once (one thread per world at a time, as in C++).
  w.def("step",
        [](PW& self, int substeps) {
          const Hold hold(self);
          const py::gil_scoped_release release;
          return self.step(substeps);
        },
        py::arg("substeps") = 1,
        "Advances by `substeps` substeps, then runs the stability guard; returns its StabilityReport.");
  w.def("advance",
        [](PW& self, double seconds) {
          const Hold hold(self);
          const py::gil_scoped_release release;
          return self.advance(seconds);
        },
        py::arg("seconds"),
        "Advances by `seconds` in equal substeps, landing exactly on time + seconds.");
  w.def("run_frames",
        [](PW& self, int frames, int substeps_per_frame, const py::function& on_frame) {
          const Hold hold(self);
          py::gil_scoped_release release;
          return self.run_frames(frames, substeps_per_frame, [&](int frame) {
            py::gil_scoped_acquire acquire;
            const py::object r = on_frame(frame);
            return r.is_none() || r.cast<bool>();  // returning False stops the run
          });
        },
        py::arg("frames"), py::arg("substeps_per_frame"), py::arg("on_frame"),
        "`frames` times: step(substeps_per_frame), then on_frame(frame); on_frame returning False stops. Returns "
        "the frames run.");
  w.def("check", locked<PW>(&W::check));
  w.def_property_readonly("halted", locked<PW>(&W::halted));
  w.def_property_readonly("substep_dt", locked<PW>(&W::substep_dt));
  w.def_property_readonly("definition", locked<PW>([](const W& self) { return WorldDef(self.def()); }),
                          "A copy of the world's WorldDef (change it with set_dt, set_integrator, ...).");
  w.def("set_integrator",
        locked<PW>([](W& self, const py::object& i) { self.set_integrator(enum_value<Integrator>(i)); }),
        py::arg("integrator"));
  w.def("set_dt", locked<PW>(&W::set_dt), py::arg("dt"));
  w.def("set_adaptive", locked<PW>(&W::set_adaptive), py::arg("adaptive"), py::arg("safety") = 0.8);
  w.def("set_cg", locked<PW>(&W::set_cg), py::arg("tolerance"), py::arg("max_iterations"));
  w.def("solver_stats", locked<PW>(&W::solver_stats), py::arg("sheet"));
  w.def_property_readonly("time", locked<PW>(&W::time));
  w.def("set_threads", locked<PW>(&W::set_threads), py::arg("threads"));
  w.def_property_readonly("contact_pair_count", locked<PW>(&W::contact_pair_count));
  w.def_property_readonly("frame_stats", locked<PW>(&W::frame_stats),
                          "Frames tried in groups of sheets in contact: kept, and undone (stepped again substep by "
                          "substep because two groups met).");
  w.def_property("step_count", locked<PW>(&W::step_count), locked<PW>(&W::set_step_count));
  w.def("diagnostics", locked<PW>(&W::diagnostics), py::arg("sheet"));
  w.def("obstacle_penetration", locked<PW>(&W::obstacle_penetration), py::arg("sheet"),
        "How deep the sheet's deepest point lies inside an obstacle (depth in m, obstacle, point).");
  w.def("sheet_crossings", locked<PW>(&W::sheet_crossings),
        "Pairs of sheets that pass through each other now (a == b: a self-colliding sheet through itself).");
  w.def("energies", locked<PW>(&W::energies));
  w.def("contact_energy", locked<PW>(&W::contact_energy),
        "J: the sheet-sheet contact potential energies() leaves out (a search).");
  w.def("all_finite", locked<PW>(&W::all_finite));
  w.def("stable_step_estimate", locked<PW>(py::overload_cast<SheetId>(&W::stable_step_estimate, py::const_)),
        py::arg("sheet"));
  w.def("stable_step_estimate", locked<PW>(py::overload_cast<>(&W::stable_step_estimate, py::const_)));
  w.def("critical_step",
        locked<PW>([](const W& self, const py::object& i) { return self.critical_step(enum_value<Integrator>(i)); }),
        py::arg("integrator"));
  w.def("contact_step_estimate", locked<PW>(&W::contact_step_estimate), py::arg("sheet"));
  w.attr("dtype") = py::dtype::of<Real>();

  using SolverStats = typename W::SolverStats;
  using FrameStats = typename W::FrameStats;
  Readout<SolverStats>(py::class_<SolverStats>(w, "SolverStats"))
      .field("iterations", &SolverStats::iterations)
      .field("relative_residual", &SolverStats::relative_residual)
      .field("converged", &SolverStats::converged)
      .field("unconverged_solves", &SolverStats::unconverged_solves)
      .done();
  Readout<FrameStats>(py::class_<FrameStats>(w, "FrameStats"))
      .field("kept", &FrameStats::kept)
      .field("undone", &FrameStats::undone)
      .done();
}

template <class Id>
void bind_id(py::module_& m, const char* name) {
  py::class_<Id>(m, name, "A handle the world hands out: pool index and generation.")
      .def_readonly("index", &Id::index)
      .def_readonly("generation", &Id::generation)
      .def_property_readonly("is_valid", &Id::is_valid)
      .def(py::self == py::self)
      .def("__hash__", [](const Id& id) { return py::hash(py::make_tuple(id.index, id.generation)); })
      .def("__repr__", [name](const Id& id) {
        if (!id.is_valid()) return std::string(name) + "(invalid)";
        return std::string(name) + "(" + std::to_string(id.index) + ", generation " + std::to_string(id.generation) + ")";
      });
}

// A scene's world with its sheets and obstacles, in the precision the scene asks for.
py::object scene_world(const app::Scene& scene, int threads) {
  std::vector<SheetId> ids;
  if (scene.precision == app::Precision::Float32)
    return py::cast(PyWorld<float>(app::build_world<float>(scene, threads, ids)));
  return py::cast(PyWorld<double>(app::build_world<double>(scene, threads, ids)));
}

// A Python value for `--set PATH=VALUE`: a str is taken as written (JSON or a bare word, as
// on the command line), anything else as its JSON text.
std::vector<app::SceneOverride> overrides_from(const py::dict& overrides) {
  std::vector<app::SceneOverride> out;
  const py::object dumps = py::module_::import("json").attr("dumps");
  for (const auto& [key, value] : overrides) {
    const std::string text = py::isinstance<py::str>(value) ? value.cast<std::string>() : dumps(value).cast<std::string>();
    out.push_back({key.cast<std::string>(), text});
  }
  return out;
}

}  // namespace

PYBIND11_MODULE(drape, m) {
  m.doc() =
      "drape: elastic sheets as mass-spring grids (Gudukbay, Ozguc, Tokad 1997). Bindings of the C++ engine: "
      "World (float64) and WorldF (float32), definitions with keyword arguments, state as NumPy views. "
      "See docs/python.md.";

  m.attr("__version__") = DRAPE_VERSION;
  py::register_exception<app::SceneError>(m, "SceneError", PyExc_ValueError);

  // The values from the integrator table (types.h), so a new integrator needs no line here.
  py::enum_<Integrator> integrator(m, "Integrator");
  for (const IntegratorInfo& info : integrator_table())
    integrator.value(python_name(info.name).c_str(), info.integrator, std::string(info.stability).c_str());
  integrator
      .def(py::init([](const std::string& name) {
             const auto i = integrator_from_name(name);
             if (!i) throw py::value_error("unknown integrator \"" + name + "\"");
             return *i;
           }),
           py::arg("name"), "From the scene format's name: \"semi_implicit_euler\", \"rk4\", ...")
      .def_property_readonly("label", [](Integrator i) { return std::string(integrator_name(i)); })
      .def_property_readonly("order", &integrator_order)
      .def_property_readonly("stability", [](Integrator i) { return std::string(integrator_info(i).stability); },
                             "the stability limit, in words")
      .def_property_readonly("knobs", [](Integrator i) { return std::string(integrator_info(i).knobs); },
                             "the WorldDef fields it reads beyond dt and gravity")
      .def_property_readonly("is_explicit", &integrator_is_explicit)
      .def("critical_step", &integrator_critical_step, py::arg("omega_max"));
  py::implicitly_convertible<std::string, Integrator>();

  py::enum_<Preconditioner>(m, "Preconditioner", "implicit Euler's CG preconditioner (WorldDef.cg_preconditioner)")
      .value("Auto", Preconditioner::Auto)
      .value("BlockJacobi", Preconditioner::BlockJacobi)
      .value("Cholesky", Preconditioner::Cholesky)
      .def(py::init([](const std::string& name) {
             const auto p = preconditioner_from_name(name);
             if (!p) throw py::value_error("unknown preconditioner \"" + name + "\"");
             return *p;
           }),
           py::arg("name"), "From the scene format's name: \"auto\", \"block_jacobi\", \"cholesky\"");
  py::implicitly_convertible<std::string, Preconditioner>();

  bind_named_enum<ObstacleShape>(m, "ObstacleShape", obstacle_shape_name, "obstacle shape");
  py::enum_<StabilityStatus>(m, "StabilityStatus")
      .value("Stable", StabilityStatus::Stable)
      .value("EnergyGrowth", StabilityStatus::EnergyGrowth)
      .value("NonFinite", StabilityStatus::NonFinite);
  py::enum_<StepLimit>(m, "StepLimit")
      .value("Springs", StepLimit::Springs)
      .value("Contact", StepLimit::Contact);

  bind_id<SheetId>(m, "SheetId");
  bind_id<ObstacleId>(m, "ObstacleId");
  bind_id<ConstraintId>(m, "ConstraintId");
  bind_named_enum<ConstraintKind>(m, "ConstraintKind", constraint_kind_name, "constraint kind");

  Fields<StiffnessRegion>(m, "StiffnessRegion", "Springs inside rows/columns [begin, end] get this stiffness (§5.1).")
      .field("row_begin", &StiffnessRegion::row_begin, "")
      .field("row_end", &StiffnessRegion::row_end, "")
      .field("col_begin", &StiffnessRegion::col_begin, "")
      .field("col_end", &StiffnessRegion::col_end, "")
      .field("stiffness", &StiffnessRegion::stiffness, "N/m")
      .done();
  Fields<AnchorDef>(m, "AnchorDef", "eq (8): a spring from a grid point to a fixed point in space.")
      .field("point", &AnchorDef::point, "point index i*(n+1)+j")
      .field("stiffness", &AnchorDef::stiffness, "N/m")
      .field("target", &AnchorDef::target, "m; None: the point's initial position")
      .done();

  Fields<ShearDef>(m, "ShearDef", "Shear springs on both diagonals of every cell (eq 6).")
      .field("stiffness", &ShearDef::stiffness, "N/m")
      .field("rest_length", &ShearDef::rest_length, "m; None: the rest cell's diagonal")
      .done();
  Fields<BendingDef>(m, "BendingDef", "Quadratic bending, 1/2 k_b sum |x_a - 2 x_b + x_c|^2 along grid lines.")
      .field("stiffness", &BendingDef::stiffness, "k_b, N/m")
      .done();
  Fields<AirDef>(m, "AirDef", "Air pressure and skin friction per cell, against WorldDef.wind.")
      .field("drag", &AirDef::drag, "C_n")
      .field("friction", &AirDef::friction, "C_t")
      .done();

  Fields<SheetDef>(m, "SheetDef", "One elastic sheet: (m+1)x(n+1) points, row-major (eqs 2-3). SI units.")
      .field("m", &SheetDef::m, "cells vertically (rows 0..m)")
      .field("n", &SheetDef::n, "cells horizontally (columns 0..n)")
      .field("width", &SheetDef::width, "Lh, m")
      .field("height", &SheetDef::height, "Lv, m")
      .field("center", &SheetDef::center, "m")
      .field("orientation", &SheetDef::orientation, "unit quaternion (w, x, y, z)")
      .field("initial_velocity", &SheetDef::initial_velocity, "m/s, every point")
      .field("mass", &SheetDef::mass, "kg, whole sheet")
      .field("point_masses", &SheetDef::point_masses, "kg per point; overrides mass when given")
      .field("stiffness", &SheetDef::stiffness, "k, N/m")
      .field("stiffness_regions", &SheetDef::stiffness_regions, "list of StiffnessRegion")
      .field("rest_length_h", &SheetDef::rest_length_h, "m; None: the spacing h1")
      .field("rest_length_v", &SheetDef::rest_length_v, "m; None: the spacing h2")
      .field("shear", &SheetDef::shear, "ShearDef or None")
      .field("bending", &SheetDef::bending, "BendingDef or None")
      .field("air", &SheetDef::air, "AirDef or None")
      .field("damping", &SheetDef::damping, "C of eq (4), N*s/m per point")
      .field("point_damping", &SheetDef::point_damping, "per point; overrides damping when given")
      .field("anchors", &SheetDef::anchors, "list of AnchorDef")
      .field("pins", &SheetDef::pins, "point indices that never move")
      .field("self_collision", &SheetDef::self_collision, "contacts of the sheet with itself")
      .field("friction", &SheetDef::friction, "mu, Coulomb, against obstacles and sheets")
      .done();

  Fields<Pose>(m, "Pose", "A rigid transform x -> rotation*x + translation.")
      .field("rotation", &Pose::rotation, "unit quaternion (w, x, y, z)")
      .field("translation", &Pose::translation, "m")
      .done();
  Fields<Keyframe>(m, "Keyframe", "At `time`, turned by `rotation` about the motion's pivot, then moved by `translation`.")
      .field("time", &Keyframe::time, "s")
      .field("translation", &Keyframe::translation, "m")
      .field("rotation", &Keyframe::rotation, "unit quaternion (w, x, y, z)")
      .done();
  Fields<CirclePath>(m, "CirclePath", "A point carried round a circle about the axis through `center`.")
      .field("center", &CirclePath::center, "m")
      .field("axis", &CirclePath::axis, "")
      .field("start", &CirclePath::start, "m; its distance from the axis is the radius")
      .field("period", &CirclePath::period, "s, one turn")
      .done();
  Fields<Motion> motion(m, "Motion", "A prescribed rigid motion over time: keyframes, a circle, or a callback.");
  py::enum_<Motion::Kind>(motion.cls(), "Kind")
      .value("Keyframes", Motion::Kind::Keyframes)
      .value("Circle", Motion::Kind::Circle)
      .value("Callback", Motion::Kind::Callback);
  motion.field("kind", &Motion::kind, "Motion.Kind")
      .field("pivot", &Motion::pivot, "m, what keyframe rotations turn about")
      .field("keyframes", &Motion::keyframes, "list of Keyframe, times increasing")
      .field("repeat", &Motion::repeat, "keyframes loop")
      .field("circle", &Motion::circle, "CirclePath")
      .field("callback", &Motion::callback, "time (s) -> Pose; pure; called by step() with the GIL taken")
      .done();

  Fields<ObstacleDef>(m, "ObstacleDef", "A rigid obstacle with the repulsion potential c*exp(-f/xi) of eq (9).")
      .field("shape", &ObstacleDef::shape, "ObstacleShape")
      .field("center", &ObstacleDef::center, "m")
      .field("orientation", &ObstacleDef::orientation, "unit quaternion (w, x, y, z)")
      .field("size", &ObstacleDef::size, "m, meaning per shape")
      .field("c", &ObstacleDef::c, "J, strength")
      .field("xi", &ObstacleDef::xi, "m, decay length")
      .field("full_gradient", &ObstacleDef::full_gradient, "use -grad E instead of its normal projection")
      .field("max_exponent", &ObstacleDef::max_exponent, "cap of -f/xi")
      .field("friction", &ObstacleDef::friction, "mu, Coulomb")
      .field("damping", &ObstacleDef::damping, "alpha, s/m: Hunt-Crossley damping of the repulsion; 0: none")
      .field("motion", &ObstacleDef::motion, "Motion or None: a rigid part that moves")
      .done();

  Fields<ConstraintDef>(m, "ConstraintDef", "Points held by eq (8) springs to targets set every substep (5.2).")
      .field("kind", &ConstraintDef::kind, "ConstraintKind")
      .field("stiffness", &ConstraintDef::stiffness, "N/m per point")
      .field("sheet", &ConstraintDef::sheet, "SheetId")
      .field("points", &ConstraintDef::points, "point indices of `sheet`")
      .field("other_sheet", &ConstraintDef::other_sheet, "PointToPoint: SheetId")
      .field("other_points", &ConstraintDef::other_points, "PointToPoint: as many as points")
      .field("rest_length", &ConstraintDef::rest_length, "PointToPoint: m; 0 welds")
      .field("motion", &ConstraintDef::motion, "Path, Frame: Motion")
      .field("carrier", &ConstraintDef::carrier, "Frame: ObstacleId whose motion carries the points, or None")
      .field("rail", &ConstraintDef::rail, "Rail: polyline of at least two knots, m")
      .done();

  Fields<Wind>(m, "Wind", "The air sheets with SheetDef.air move in: uniform and steady.")
      .field("velocity", &Wind::velocity, "m/s")
      .field("density", &Wind::density, "rho, kg/m^3")
      .done();

  Fields<WorldDef>(m, "WorldDef", "The world's step, gravity, integrator, threads, guard and contact parameters.")
      .field("dt", &WorldDef::dt, "s, one substep")
      .field("gravity", &WorldDef::gravity, "m/s^2")
      .field("integrator", &WorldDef::integrator, "Integrator (or its name)")
      .field("wind", &WorldDef::wind, "Wind")
      .field("threads", &WorldDef::threads, "worker threads of step(); 0: all cores")
      .field("cg_tolerance", &WorldDef::cg_tolerance, "implicit Euler's CG stop")
      .field("cg_max_iterations", &WorldDef::cg_max_iterations, "implicit Euler's CG stop")
      .field("cg_preconditioner", &WorldDef::cg_preconditioner, "Preconditioner (or its name)")
      .field("local_global_iterations", &WorldDef::local_global_iterations, "LocalGlobal's iterations per step")
      .field("vertex_block_iterations", &WorldDef::vertex_block_iterations, "VertexBlockDescent's iterations per step")
      .field("adaptive", &WorldDef::adaptive, "explicit integrators take their largest stable substep")
      .field("adaptive_safety", &WorldDef::adaptive_safety, "in (0, 1]")
      .field("guard", &WorldDef::guard, "stability guard after every step()/advance()")
      .field("guard_energy_growth", &WorldDef::guard_energy_growth, "")
      .field("contact_thickness", &WorldDef::contact_thickness, "h, m")
      .field("contact_xi", &WorldDef::contact_xi, "xi, m")
      .field("contact_strength", &WorldDef::contact_strength, "c, J; 0: no contacts")
      .field("contact_range", &WorldDef::contact_range, "cut-off beyond h, in units of xi")
      .field("contact_damping", &WorldDef::contact_damping, "alpha, s/m: Hunt-Crossley damping of the repulsion (default 2); 0: none, the repulsion conserves energy")
      .field("contact_exact", &WorldDef::contact_exact, "exact nearest triangle every substep (the reference)")
      .field("contact_rims", &WorldDef::contact_rims, "rim edges also repel the other sheet's edges (default True)")
      .field("block_points", &WorldDef::block_points, "points per row block of a large sheet")
      .field("group_points", &WorldDef::group_points, "worlds of at least this many points try frames in groups of sheets in contact (0: all)")
      .done();

  Readout<Energies>(py::class_<Energies>(m, "Energies", "J"))
      .field("kinetic", &Energies::kinetic)
      .field("spring", &Energies::spring)
      .field("bending", &Energies::bending)
      .field("gravity", &Energies::gravity)
      .field("anchor", &Energies::anchor)
      .field("obstacle", &Energies::obstacle)
      .property("total", &Energies::total)
      .done();
  Readout<SheetDiagnostics>(py::class_<SheetDiagnostics>(m, "SheetDiagnostics"))
      .field("energy", &SheetDiagnostics::energy)
      .field("max_strain", &SheetDiagnostics::max_strain)
      .field("finite", &SheetDiagnostics::finite)
      .done();
  Readout<ObstaclePenetration>(py::class_<ObstaclePenetration>(m, "ObstaclePenetration"))
      .field("depth", &ObstaclePenetration::depth)
      .field("obstacle", &ObstaclePenetration::obstacle)
      .field("point", &ObstaclePenetration::point)
      .done();
  Readout<SheetCrossing>(py::class_<SheetCrossing>(m, "SheetCrossing"))
      .field("a", &SheetCrossing::a)
      .field("b", &SheetCrossing::b)
      .field("edges", &SheetCrossing::edges)
      .field("point_a", &SheetCrossing::point_a)
      .field("point_b", &SheetCrossing::point_b)
      .done();
  py::class_<StabilityReport>(m, "StabilityReport", "What the stability guard found; str() describes it.")
      .def_readonly("status", &StabilityReport::status)
      .def_readonly("sheet", &StabilityReport::sheet)
      .def_readonly("step", &StabilityReport::step)
      .def_readonly("time", &StabilityReport::time)
      .def_readonly("energy_growth", &StabilityReport::energy_growth)
      .def_readonly("integrator", &StabilityReport::integrator)
      .def_readonly("dt", &StabilityReport::dt)
      .def_readonly("stable_dt", &StabilityReport::stable_dt)
      .def_readonly("stable_integrator", &StabilityReport::stable_integrator)
      .def_readonly("step_limit", &StabilityReport::step_limit)
      .def_readonly("unconverged_solves", &StabilityReport::unconverged_solves)
      .def_property_readonly("ok", &StabilityReport::ok)
      .def("__bool__", &StabilityReport::ok)
      .def("__str__", [](const StabilityReport& r) { return describe(r); })
      .def("__repr__", [](const StabilityReport& r) { return "<drape.StabilityReport: " + describe(r) + ">"; });

  py::class_<SheetKeeper>(m, "_SheetKeeper", "What a sheet's arrays keep alive: the world, or the removed sheet's buffers.");
  py::class_<SheetArrays>(m, "SheetArrays",
                          "A sheet's state as (m+1, n+1) arrays over the world's buffers; valid until the next "
                          "add_sheet/remove_sheet on that world.")
      .def_readonly("m", &SheetArrays::m)
      .def_readonly("n", &SheetArrays::n)
      .def_readonly("x", &SheetArrays::x)
      .def_readonly("y", &SheetArrays::y)
      .def_readonly("z", &SheetArrays::z)
      .def_readonly("vx", &SheetArrays::vx)
      .def_readonly("vy", &SheetArrays::vy)
      .def_readonly("vz", &SheetArrays::vz)
      .def("__repr__", [](const SheetArrays& a) {
        return "SheetArrays(m=" + std::to_string(a.m) + ", n=" + std::to_string(a.n) + ", " +
               std::string(py::str(a.x.dtype())) + (a.x.writeable() ? ", writable)" : ", read-only)");
      });

  bind_world<double>(m, "World", "A world of sheets stored and stepped in float64.");
  bind_world<float>(m, "WorldF", "A world of sheets stored and stepped in float32.");

  m.def("validate", py::overload_cast<const SheetDef&>(&validate), py::arg("definition"),
        "'' when usable, else one message naming the field.");
  m.def("validate_float", &validate_float, py::arg("definition"),
        "validate() for a WorldF: also whether float32 coordinates resolve the sheet's cells.");
  m.def("validate", py::overload_cast<const WorldDef&>(&validate), py::arg("definition"));
  m.def("validate", py::overload_cast<const ObstacleDef&>(&validate), py::arg("definition"));
  m.def("validate", py::overload_cast<const Motion&>(&validate), py::arg("definition"));
  m.def("corner_points", &corner_points, py::arg("m"), py::arg("n"));
  m.def("center_point", &center_point, py::arg("m"), py::arg("n"));
  m.def("anchors_at", [](const std::vector<std::uint32_t>& points, double k) { return anchors_at(points, k); },
        py::arg("points"), py::arg("stiffness"));
  m.def("point_index", &point_index, py::arg("n"), py::arg("i"), py::arg("j"));
  m.def("point_count", &point_count, py::arg("m"), py::arg("n"));
  m.def("spring_count", &spring_count, py::arg("m"), py::arg("n"));
  m.def("row_points", &row_points, py::arg("m"), py::arg("n"), py::arg("i"), "every point of row i, columns 0..n");
  m.def("column_points", &column_points, py::arg("m"), py::arg("n"), py::arg("j"), "every point of column j, rows 0..m");
  m.def("pose_at", &pose_at, py::arg("motion"), py::arg("time"));
  m.def("obstacle_at", &obstacle_at, py::arg("definition"), py::arg("time"));
  m.def("apply", &apply, py::arg("pose"), py::arg("x"));
  m.def("inverse", &inverse, py::arg("pose"));
  m.def("compose", &compose, py::arg("outer"), py::arg("inner"), "x -> outer(inner(x))");
  m.def("multiply", &multiply, py::arg("a"), py::arg("b"), "rotate by b, then by a");
  m.def("quat_from_axis_angle", &quat_from_axis_angle, py::arg("axis"), py::arg("radians"));
  m.def("rotate", &rotate, py::arg("q"), py::arg("v"));

  py::class_<app::Scene>(m, "Scene", "A scene file, read and checked (docs/scene-format.md).")
      .def_readonly("file", &app::Scene::file)
      .def_readonly("description", &app::Scene::description)
      .def_readonly("world", &app::Scene::world)
      .def_property_readonly("precision", [](const app::Scene& s) { return std::string(app::precision_name(s.precision)); })
      .def_readonly("fps", &app::Scene::fps)
      .def_readonly("substeps", &app::Scene::substeps)
      .def_readonly("frames", &app::Scene::frames)
      .def_readonly("sheet_names", &app::Scene::sheet_names)
      .def_readonly("sheets", &app::Scene::sheets)
      .def_readonly("obstacles", &app::Scene::obstacles)
      .def_readonly("constraints", &app::Scene::constraints,
                    "ConstraintDefs whose sheet/other_sheet/carrier index is the position in sheets/obstacles")
      .def_readonly("fingerprint", &app::Scene::fingerprint)
      .def_property_readonly("frame_time", &app::Scene::frame_time)
      .def("make_world", &scene_world, py::arg("threads") = 0,
           "A World (float64) or WorldF (float32, by the scene's precision) holding the scene's sheets, in the "
           "scene's order, and obstacles; stepping it `substeps` at a time gives drape run's frames.");
  m.def("load_scene",
        [](const std::filesystem::path& file, const py::dict& overrides) {
          const auto o = overrides_from(overrides);
          return app::load_scene(file, o);
        },
        py::arg("file"), py::arg("overrides") = py::dict(),
        "Reads and checks a scene file; overrides maps a field path ('dt', 'sheets[*].stiffness') to a value, as "
        "drape sweep --set does. SceneError (a ValueError) names the file, the field and the problem.");
  m.def("parse_scene",
        [](const std::string& text, const std::string& name, const py::dict& overrides) {
          const auto o = overrides_from(overrides);
          return app::parse_scene(text, name, o);
        },
        py::arg("text"), py::arg("name") = "<string>", py::arg("overrides") = py::dict(),
        "load_scene from the text of a scene file.");
}
