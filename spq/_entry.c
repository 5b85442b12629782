/* spq._entry: the per-call queries' entry points in C (optional; spq.query falls back to Python).

A per-call query's own work is about 1.2 us; the Python around it (the key and pose checks, the
result array and object) was another 0.7 us. Here that Python is C, and the query itself is
kb.query_one compiled as a C function (spq.kernels.query_cfunc), called through its address.

Anything but the common case takes the Python function this wraps (`fallback`), which does the same
query, so answers are bit for bit the same and errors come from one place: keywords other than the
options, poses that are not C-ordered aligned native float64 4x4 ndarrays, a pair seen for the
first time, and a pose the kernel rejected (whose message Python writes). A NaN distance of the
kernel's own is a result, as in Python.

Types:
- result_type(doc): spq.DistanceResult, made once by spq.query: the result vector (OUT_SIZE doubles)
  in the object, which the kernel writes into, and its fields read in C. No Python subclass (which
  would take part in the garbage collector) and no object pointers (the distance is a double), so a
  call's result costs no collector bookkeeping, and freed results are kept for the next calls.
- Entry(address, state, packed_a, packed_b): one pair's compiled query (a Pair's arrays).
- PlainDistance(fallback, defaults): spq.distance. The last pair it asked on this thread is kept by
  remember(A, B, tol, rel_tol, max_iter, signed, entry), which the fallback calls, and a call whose
  shapes and options are the same objects (identity) reuses its Entry.
- PairQuery(fallback, coherent): Pair.distance and Pair.cold_distance, a method (a descriptor);
  it reads the Pair's `_entry`.
configure(result_type, layout, status_names, work[, old_order]) says which result type the queries make
(result_type's), where each field lies in the result vector (spq.kernels.gjk's OUT_*; a NaN distance whose
status is < 0 is a rejected pose), the status names, and kb.query_work's array, which the module keeps;
old_order (spq.query._OLD_ORDER), whose "warned" lets PlainDistance take spq 0.1's argument order,
distance(A, pose_a, B, pose_b), once Python has warned about it.
*/
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <structmember.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

typedef double (*query_fn)(double *, int64_t, double *, int64_t, double *, int64_t, double *, double *, int64_t,
                           double *, double *, int64_t);

/* configure()'s, held for the process */
static PyTypeObject *result_type = NULL; /* a subclass of Result: spq.DistanceResult */
static PyObject *status_names = NULL;     /* a tuple */
/* the result vector's layout (spq.kernels.gjk's OUT_*): its size, then where each field is (the
   distance is the kernel's return value, kept as a float beside the vector) */
enum { L_SIZE, L_POINT_A, L_POINT_B, L_NORMAL, L_LOWER, L_UPPER, L_ITERATIONS, L_STATUS, L_COUNT };
static Py_ssize_t layout[L_COUNT];
/* One work array for every thread: a query here holds the GIL from start to end (kb.query_one does
   not release it, and a module of this kind keeps the GIL on a free-threaded build), so no two
   queries use it at once. */
static PyArrayObject *work = NULL;
static PyObject *last_key = NULL, *entry_attr = NULL; /* interned strings */
/* The last thread that asked and its `last` (remember()'s tuple, or NULL): the dict lookups it saves
   are about 1% of a plain call. A thread's state may be freed and its address reused by a new thread,
   which then starts from the old one's tuple; a call takes an Entry only for the same objects as its
   own (identity), so that answers alike. */
static PyThreadState *last_thread = NULL;
static PyObject *last_of_thread = NULL;
/* spq.query._OLD_ORDER (configure()'s, or NULL): spq 0.1's argument order, distance(A, pose_a, B, pose_b),
   takes this path only once Python has given its one DeprecationWarning ("warned" true) */
static PyObject *old_order = NULL, *warned_key = NULL;

/* ---------------------------------------------------------------- Entry */

typedef struct {
    PyObject_HEAD
    query_fn fn;
    PyObject *arrays[3]; /* state, packed_a, packed_b */
    double *data[3];
    int64_t size[3];
} EntryObject;

/* a 1-D native float64 array the kernel can take as it is (and write to, if writeable) */
static int is_flat_f64(PyObject *o, int writeable) {
    if (!PyArray_Check(o)) return 0;
    PyArrayObject *a = (PyArrayObject *)o;
    return PyArray_TYPE(a) == NPY_FLOAT64 && PyArray_ISNOTSWAPPED(a) && PyArray_NDIM(a) == 1 &&
           PyArray_CHKFLAGS(a, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED) &&
           (!writeable || PyArray_CHKFLAGS(a, NPY_ARRAY_WRITEABLE));
}

static PyObject *entry_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    PyObject *address, *arrays[3];
    static char *names[] = {"address", "state", "packed_a", "packed_b", NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!OOO:Entry", names, &PyLong_Type, &address, &arrays[0],
                                     &arrays[1], &arrays[2]))
        return NULL;
    void *fn = PyLong_AsVoidPtr(address);
    if (fn == NULL) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "Entry: address must be a function's, not 0");
        return NULL;
    }
    for (int i = 0; i < 3; i++) {
        if (!is_flat_f64(arrays[i], i == 0)) {
            PyErr_Format(PyExc_ValueError, "Entry: argument %d must be a C-contiguous, aligned 1-D float64 array "
                         "(the state writeable)", i + 2);
            return NULL;
        }
    }
    EntryObject *self = (EntryObject *)type->tp_alloc(type, 0);
    if (self == NULL) return NULL;
    self->fn = (query_fn)fn;
    for (int i = 0; i < 3; i++) {
        self->arrays[i] = Py_NewRef(arrays[i]);
        self->data[i] = (double *)PyArray_DATA((PyArrayObject *)arrays[i]);
        self->size[i] = (int64_t)PyArray_SIZE((PyArrayObject *)arrays[i]);
    }
    return (PyObject *)self;
}

static void entry_dealloc(EntryObject *self) {
    for (int i = 0; i < 3; i++) Py_XDECREF(self->arrays[i]);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyTypeObject EntryType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "spq._entry.Entry",
    .tp_doc = PyDoc_STR("Entry(address, state, packed_a, packed_b): one pair's compiled query, its arrays held"),
    .tp_basicsize = sizeof(EntryObject),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = entry_new,
    .tp_dealloc = (destructor)entry_dealloc,
};

/* ---------------------------------------------------------------- Result */

#define RESULT_CAPACITY 16 /* doubles: the result vector, OUT_SIZE of them, lives in the object */
#define RESULT_FREE 16     /* freed results kept for the next calls (a loop holds one or two at a time) */

typedef struct {
    PyObject_HEAD
    double distance; /* a member (a slot's fast read): the float is made when it is read */
    double out[RESULT_CAPACITY];
} ResultObject;

static PyTypeObject *made_type = NULL; /* result_type()'s */
static ResultObject *free_results[RESULT_FREE];
static int free_count = 0;

static void result_dealloc(ResultObject *self) {
    PyTypeObject *type = Py_TYPE(self);
    if (free_count < RESULT_FREE)
        free_results[free_count++] = self; /* its memory, for new_result's PyObject_Init */
    else
        type->tp_free((PyObject *)self);
    Py_DECREF(type); /* an instance of a heap type holds a reference to it */
}

/* a zeroed result of the configured type, a kept one if there is one */
static ResultObject *new_result(void) {
    if (free_count == 0) return (ResultObject *)result_type->tp_alloc(result_type, 0);
    ResultObject *self = free_results[--free_count];
    PyObject_Init((PyObject *)self, result_type); /* (a reference to the type, and one to the object) */
    self->distance = 0.0;
    memset(self->out, 0, sizeof(self->out));
    return self;
}

/* a new 1-D float64 array holding n doubles from data */
static PyObject *new_vector(const double *data, npy_intp n) {
    PyObject *a = PyArray_SimpleNew(1, &n, NPY_FLOAT64);
    if (a != NULL) memcpy(PyArray_DATA((PyArrayObject *)a), data, (size_t)n * sizeof(double));
    return a;
}

/* point_a, point_b, normal: a fresh 3-vector each read, as the Python fields' copies */
static PyObject *result_vector(ResultObject *self, void *field) {
    return new_vector(self->out + layout[(Py_ssize_t)field], 3);
}

static PyObject *result_float(ResultObject *self, void *field) {
    return PyFloat_FromDouble(self->out[layout[(Py_ssize_t)field]]);
}

/* as Python's int() of the float: truncated, and an error for NaN or inf */
static PyObject *result_int(ResultObject *self, void *field) {
    return PyLong_FromDouble(self->out[layout[(Py_ssize_t)field]]);
}

static PyObject *result_status(ResultObject *self, void *unused) {
    PyObject *code = result_int(self, (void *)L_STATUS);
    if (code == NULL) return NULL;
    if (status_names == NULL) { /* a Result made before spq.query configured the module */
        Py_DECREF(code);
        PyErr_SetString(PyExc_RuntimeError, "spq._entry is not configured (import spq first)");
        return NULL;
    }
    PyObject *name = PyObject_GetItem(status_names, code); /* as STATUS_NAMES[int(...)] */
    Py_DECREF(code);
    return name;
}

static PyObject *result_get_out(ResultObject *self, void *unused) {
    return new_vector(self->out, layout[L_SIZE]);
}

/* _out = array: its OUT_SIZE values copied in (the Python path's result array) */
static int result_set_out(ResultObject *self, PyObject *value, void *unused) {
    if (value == NULL) {
        PyErr_SetString(PyExc_AttributeError, "_out cannot be deleted");
        return -1;
    }
    PyArrayObject *a = (PyArrayObject *)PyArray_FROM_OTF(value, NPY_FLOAT64, NPY_ARRAY_IN_ARRAY);
    if (a == NULL) return -1;
    if (PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != layout[L_SIZE]) {
        PyErr_Format(PyExc_ValueError, "_out must be a 1-D array of %zd floats", layout[L_SIZE]);
        Py_DECREF(a);
        return -1;
    }
    memcpy(self->out, PyArray_DATA(a), (size_t)layout[L_SIZE] * sizeof(double));
    Py_DECREF(a);
    return 0;
}

static PyGetSetDef result_getset[] = {
    {"_out", (getter)result_get_out, (setter)result_set_out, PyDoc_STR("the result vector (a copy)"), NULL},
    {"point_a", (getter)result_vector, NULL, PyDoc_STR("witness point on A (3,)"), (void *)L_POINT_A},
    {"point_b", (getter)result_vector, NULL, PyDoc_STR("witness point on B (3,)"), (void *)L_POINT_B},
    {"normal", (getter)result_vector, NULL, PyDoc_STR("unit vector from A to B (3,)"), (void *)L_NORMAL},
    {"status", (getter)result_status, NULL, PyDoc_STR("'separated', 'touching', 'overlapping' or 'failed'"), NULL},
    {"iterations", (getter)result_int, NULL, PyDoc_STR("GJK (plus EPA) iterations"), (void *)L_ITERATIONS},
    {"lower_bound", (getter)result_float, NULL, PyDoc_STR("certified lower bound"), (void *)L_LOWER},
    {"upper_bound", (getter)result_float, NULL, PyDoc_STR("certified upper bound"), (void *)L_UPPER},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyMemberDef result_members[] = {
    {"distance", T_DOUBLE, offsetof(ResultObject, distance), 0, PyDoc_STR("the distance (m), a float")},
    {NULL, 0, 0, 0, NULL},
};

/* result_type(doc): the results' type (spq.DistanceResult), with that docstring; Python adds its
   __repr__ and __reduce__ */
static PyObject *make_result_type(PyObject *module, PyObject *doc) {
    const char *text = PyUnicode_AsUTF8(doc);
    if (text == NULL) return NULL;
    PyType_Slot slots[] = {
        {Py_tp_dealloc, (void *)result_dealloc}, {Py_tp_getset, result_getset}, {Py_tp_members, result_members},
        {Py_tp_new, (void *)PyType_GenericNew}, {Py_tp_doc, (void *)text}, {0, NULL},
    };
    PyType_Spec spec = {"spq.query.DistanceResult", sizeof(ResultObject), 0, Py_TPFLAGS_DEFAULT, slots};
    PyObject *type = PyType_FromSpec(&spec);
    if (type != NULL) Py_XSETREF(made_type, (PyTypeObject *)Py_NewRef(type));
    return type;
}

/* ---------------------------------------------------------------- the query */

/* A pose the compiled query takes as it is: an ndarray (not a subclass, as Python's path), native
   float64, C-ordered 4x4, aligned. */
static inline int is_pose(PyObject *o) {
    if (!PyArray_CheckExact(o)) return 0;
    PyArrayObject *a = (PyArrayObject *)o;
    return PyArray_TYPE(a) == NPY_FLOAT64 && PyArray_ISNOTSWAPPED(a) && PyArray_NDIM(a) == 2 &&
           PyArray_DIM(a, 0) == 4 && PyArray_DIM(a, 1) == 4 &&
           PyArray_CHKFLAGS(a, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
}

/* The result of one query, or NULL: with an error set, that error; without, the fallback's turn
   (a pose this path does not take, or one the kernel rejected). The kernel writes into the result. */
static PyObject *query(EntryObject *e, PyObject *pose_a, PyObject *pose_b, int coherent) {
    if (result_type == NULL || !is_pose(pose_a) || !is_pose(pose_b)) return NULL;
    /* not tp_new: DistanceResult has no __new__ of its own, and a zeroed object is a valid one */
    ResultObject *result = new_result();
    if (result == NULL) return NULL;
    double d = e->fn(e->data[0], e->size[0], e->data[1], e->size[1], e->data[2], e->size[2],
                     (double *)PyArray_DATA((PyArrayObject *)pose_a), (double *)PyArray_DATA((PyArrayObject *)pose_b),
                     coherent, result->out, (double *)PyArray_DATA(work), (int64_t)PyArray_SIZE(work));
    if (d != d && result->out[layout[L_STATUS]] < 0) {
        Py_DECREF(result); /* a rejected pose, nothing computed: Python's path raises its error */
        return NULL;
    }
    result->distance = d;
    return (PyObject *)result;
}

/* ---------------------------------------------------------------- wrappers' common part */

typedef struct {
    PyObject_HEAD
    PyObject *fallback;
    PyObject *dict; /* __doc__, __wrapped__, __name__, ... (functools.update_wrapper) */
    vectorcallfunc vectorcall;
    PyObject *defaults[4]; /* PlainDistance: tol, rel_tol, max_iter, signed */
    int coherent;          /* PairQuery */
} WrapperObject;

static int wrapper_traverse(WrapperObject *self, visitproc visit, void *arg) {
    Py_VISIT(self->fallback);
    Py_VISIT(self->dict);
    for (int i = 0; i < 4; i++) Py_VISIT(self->defaults[i]);
    return 0;
}

static int wrapper_clear(WrapperObject *self) {
    Py_CLEAR(self->fallback);
    Py_CLEAR(self->dict);
    for (int i = 0; i < 4; i++) Py_CLEAR(self->defaults[i]);
    return 0;
}

static void wrapper_dealloc(WrapperObject *self) {
    PyObject_GC_UnTrack(self);
    wrapper_clear(self);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *wrapper_repr(WrapperObject *self) {
    return PyUnicode_FromFormat("<compiled entry to %R>", self->fallback);
}

/* pickled by reference, as a function is: its module's attribute of its name */
static PyObject *wrapper_reduce(PyObject *self, PyObject *unused) {
    return PyObject_GetAttrString(self, "__qualname__");
}

static PyObject *call_fallback(WrapperObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    return PyObject_Vectorcall(self->fallback, args, nargsf, kwnames);
}

/* a wrapper of fallback, called through vectorcall */
static WrapperObject *new_wrapper(PyTypeObject *type, PyObject *fallback, vectorcallfunc vectorcall) {
    WrapperObject *self = (WrapperObject *)type->tp_alloc(type, 0);
    if (self == NULL) return NULL;
    self->fallback = Py_NewRef(fallback);
    self->vectorcall = vectorcall;
    return self;
}

static PyMethodDef wrapper_methods[] = {
    {"__reduce__", wrapper_reduce, METH_NOARGS, NULL},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef wrapper_getset[] = {
    {"__dict__", PyObject_GenericGetDict, PyObject_GenericSetDict, NULL, NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

/* the slots both wrapper types share */
#define WRAPPER_SLOTS                                                 \
    .tp_basicsize = sizeof(WrapperObject),                            \
    .tp_dealloc = (destructor)wrapper_dealloc,                        \
    .tp_traverse = (traverseproc)wrapper_traverse,                    \
    .tp_clear = (inquiry)wrapper_clear,                               \
    .tp_repr = (reprfunc)wrapper_repr,                                \
    .tp_call = PyVectorcall_Call,                                     \
    .tp_vectorcall_offset = offsetof(WrapperObject, vectorcall),      \
    .tp_dictoffset = offsetof(WrapperObject, dict),                   \
    .tp_getset = wrapper_getset

/* ---------------------------------------------------------------- PlainDistance: spq.distance */

static const char *option_names[4] = {"tol", "rel_tol", "max_iter", "signed"};
static PyObject *options[4]; /* interned */

/* the index (4 to 7) of an option's name, or 8 */
static Py_ssize_t option_index(PyObject *name) {
    for (Py_ssize_t j = 0; j < 4; j++)
        if (name == options[j]) return j + 4; /* a call's keyword names are interned: identity, mostly */
    for (Py_ssize_t j = 0; j < 4; j++)
        if (PyUnicode_Compare(name, options[j]) == 0) return j + 4;
    return 8;
}

/* whether remember()'s tuple `last` holds shapes a and b and the options v[4..7] (identity) */
static inline int is_last(PyObject *last, PyObject *a, PyObject *b, PyObject *const *v) {
    return last != NULL && PyTuple_CheckExact(last) && PyTuple_GET_SIZE(last) == 7 &&
           PyTuple_GET_ITEM(last, 0) == a && PyTuple_GET_ITEM(last, 1) == b &&
           PyTuple_GET_ITEM(last, 2) == v[4] && PyTuple_GET_ITEM(last, 3) == v[5] &&
           PyTuple_GET_ITEM(last, 4) == v[6] && PyTuple_GET_ITEM(last, 5) == v[7] &&
           Py_IS_TYPE(PyTuple_GET_ITEM(last, 6), &EntryType);
}

/* whether Python has warned about spq 0.1's argument order (a test may reset its flag to see the warning again) */
static int old_order_warned(void) {
    if (old_order == NULL) return 0;
    PyObject *w = PyDict_GetItemWithError(old_order, warned_key);
    if (w == NULL) PyErr_Clear();
    return w == Py_True;
}

static PyObject *plain_vectorcall(WrapperObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    PyObject *v[8];
    if (nargs < 4 || nargs > 8) return call_fallback(self, args, nargsf, kwnames);
    for (Py_ssize_t i = 0; i < 8; i++) v[i] = i < nargs ? args[i] : self->defaults[i - 4];
    if (kwnames != NULL) { /* the options by name; anything else is the fallback's to take or refuse */
        Py_ssize_t nkw = PyTuple_GET_SIZE(kwnames);
        for (Py_ssize_t k = 0; k < nkw; k++) {
            Py_ssize_t j = option_index(PyTuple_GET_ITEM(kwnames, k));
            if (j == 8 || j < nargs) return call_fallback(self, args, nargsf, kwnames);
            v[j] = args[nargs + k];
        }
    }
    PyObject *last = last_of_thread;
    PyThreadState *thread = PyThreadState_Get();
    if (thread != last_thread) {
        PyObject *dict = PyThreadState_GetDict();
        last = dict != NULL ? PyDict_GetItemWithError(dict, last_key) : NULL;
        if (last == NULL && PyErr_Occurred()) return NULL;
        Py_XSETREF(last_of_thread, Py_XNewRef(last));
        last_thread = thread;
    }
    PyObject *result = NULL;
    if (is_last(last, v[0], v[1], v)) /* (A, B, pose_a, pose_b) */
        result = query((EntryObject *)PyTuple_GET_ITEM(last, 6), v[2], v[3], 0);
    else if (is_last(last, v[0], v[2], v) && old_order_warned()) /* spq 0.1's (A, pose_a, B, pose_b) */
        result = query((EntryObject *)PyTuple_GET_ITEM(last, 6), v[1], v[3], 0);
    if (result != NULL || PyErr_Occurred()) return result;
    return call_fallback(self, args, nargsf, kwnames);
}

static PyObject *plain_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    PyObject *fallback, *defaults;
    static char *names[] = {"fallback", "defaults", NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OO!:PlainDistance", names, &fallback, &PyTuple_Type, &defaults))
        return NULL;
    if (!PyCallable_Check(fallback) || PyTuple_GET_SIZE(defaults) != 4) {
        PyErr_SetString(PyExc_ValueError, "PlainDistance(fallback, defaults): a callable and its 4 options' defaults");
        return NULL;
    }
    WrapperObject *self = new_wrapper(type, fallback, (vectorcallfunc)plain_vectorcall);
    if (self == NULL) return NULL;
    for (int i = 0; i < 4; i++) self->defaults[i] = Py_NewRef(PyTuple_GET_ITEM(defaults, i));
    return (PyObject *)self;
}

static PyTypeObject PlainType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "spq._entry.PlainDistance",
    .tp_doc = PyDoc_STR("PlainDistance(fallback, defaults): spq.distance's compiled entry"),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_new = plain_new,
    .tp_methods = wrapper_methods,
    WRAPPER_SLOTS,
};

/* ---------------------------------------------------------------- PairQuery: Pair's methods */

static PyObject *pair_vectorcall(WrapperObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames) {
    if (kwnames == NULL && PyVectorcall_NARGS(nargsf) == 3) { /* (pair, pose_a, pose_b) */
        PyObject *entry = PyObject_GetAttr(args[0], entry_attr);
        if (entry == NULL) { /* not a Pair as __init__ makes one: Python's path says what is wrong */
            if (!PyErr_ExceptionMatches(PyExc_AttributeError)) return NULL;
            PyErr_Clear();
            return call_fallback(self, args, nargsf, kwnames);
        }
        PyObject *result = NULL;
        if (Py_IS_TYPE(entry, &EntryType)) result = query((EntryObject *)entry, args[1], args[2], self->coherent);
        Py_DECREF(entry);
        if (result != NULL || PyErr_Occurred()) return result;
    }
    return call_fallback(self, args, nargsf, kwnames);
}

/* pair.distance: a method bound to the pair, as a function's */
static PyObject *pair_descr_get(PyObject *self, PyObject *obj, PyObject *type) {
    if (obj == NULL || obj == Py_None) return Py_NewRef(self);
    return PyMethod_New(self, obj);
}

static PyObject *pair_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    PyObject *fallback;
    int coherent;
    static char *names[] = {"fallback", "coherent", NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "Op:PairQuery", names, &fallback, &coherent)) return NULL;
    if (!PyCallable_Check(fallback)) {
        PyErr_SetString(PyExc_ValueError, "PairQuery(fallback, coherent): fallback must be callable");
        return NULL;
    }
    WrapperObject *self = new_wrapper(type, fallback, (vectorcallfunc)pair_vectorcall);
    if (self == NULL) return NULL;
    self->coherent = coherent;
    return (PyObject *)self;
}

static PyTypeObject PairQueryType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "spq._entry.PairQuery",
    .tp_doc = PyDoc_STR("PairQuery(fallback, coherent): Pair.distance's or Pair.cold_distance's compiled entry"),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL | Py_TPFLAGS_METHOD_DESCRIPTOR,
    .tp_new = pair_new,
    .tp_descr_get = pair_descr_get,
    WRAPPER_SLOTS,
};

/* ---------------------------------------------------------------- module functions */

static PyObject *remember(PyObject *module, PyObject *last) {
    if (!PyTuple_CheckExact(last) || PyTuple_GET_SIZE(last) != 7 || !Py_IS_TYPE(PyTuple_GET_ITEM(last, 6), &EntryType)) {
        PyErr_SetString(PyExc_ValueError, "remember: a tuple (A, B, tol, rel_tol, max_iter, signed, Entry)");
        return NULL;
    }
    PyObject *dict = PyThreadState_GetDict();
    if (dict == NULL || PyDict_SetItem(dict, last_key, last) < 0) return NULL;
    Py_XSETREF(last_of_thread, Py_NewRef(last));
    last_thread = PyThreadState_Get();
    Py_RETURN_NONE;
}

static PyObject *configure(PyObject *module, PyObject *args) {
    PyTypeObject *type;
    PyObject *where, *names, *work_array, *old = NULL;
    if (!PyArg_ParseTuple(args, "O!O!O!O|O!:configure", &PyType_Type, &type, &PyTuple_Type, &where, &PyTuple_Type,
                          &names, &work_array, &PyDict_Type, &old))
        return NULL;
    Py_ssize_t got[L_COUNT];
    int ok = type == made_type && PyTuple_GET_SIZE(where) == L_COUNT && is_flat_f64(work_array, 1);
    for (Py_ssize_t i = 0; ok && i < L_COUNT; i++) {
        got[i] = PyLong_AsSsize_t(PyTuple_GET_ITEM(where, i));
        if (got[i] == -1 && PyErr_Occurred()) return NULL;
        Py_ssize_t width = i == L_POINT_A || i == L_POINT_B || i == L_NORMAL ? 3 : 1;
        ok = i == L_SIZE ? got[i] >= 1 && got[i] <= RESULT_CAPACITY : got[i] >= 0 && got[i] + width <= got[L_SIZE];
    }
    if (!ok) {
        PyErr_Format(PyExc_ValueError, "configure(result_type: result_type()'s, layout: (size <= %d, "
                     "point_a, point_b, normal, lower, upper, iterations, status) within size, status_names, "
                     "work: a writeable, C-contiguous, aligned 1-D float64 array)", RESULT_CAPACITY);
        return NULL;
    }
    memcpy(layout, got, sizeof(layout));
    Py_XSETREF(status_names, Py_NewRef(names));
    Py_XSETREF(work, (PyArrayObject *)Py_NewRef(work_array));
    Py_XSETREF(result_type, (PyTypeObject *)Py_NewRef((PyObject *)type));
    Py_XSETREF(old_order, Py_XNewRef(old));
    Py_RETURN_NONE;
}

static PyMethodDef module_methods[] = {
    {"remember", remember, METH_O,
     PyDoc_STR("remember((A, B, tol, rel_tol, max_iter, signed, entry)): this thread's last plain distance() pair")},
    {"result_type", make_result_type, METH_O,
     PyDoc_STR("result_type(doc): the results' type, spq.DistanceResult (made once)")},
    {"configure", configure, METH_VARARGS,
     PyDoc_STR("configure(result_type, layout, status_names, work[, old_order]): the results' type and layout, the "
               "work array, and the dict whose 'warned' lets spq 0.1's argument order take the C path")},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, "spq._entry",
    PyDoc_STR("The per-call queries' entry points in C (optional: spq.query falls back to Python)."), -1,
    module_methods,
};

PyMODINIT_FUNC PyInit__entry(void) {
    import_array();
    if (PyType_Ready(&EntryType) < 0 || PyType_Ready(&PlainType) < 0 || PyType_Ready(&PairQueryType) < 0)
        return NULL;
    last_key = PyUnicode_InternFromString("spq._entry.last");
    entry_attr = PyUnicode_InternFromString("_entry");
    warned_key = PyUnicode_InternFromString("warned");
    for (int j = 0; j < 4; j++)
        if ((options[j] = PyUnicode_InternFromString(option_names[j])) == NULL) return NULL;
    if (last_key == NULL || entry_attr == NULL || warned_key == NULL) return NULL;
    PyObject *m = PyModule_Create(&module_def);
    if (m == NULL) return NULL;
    if (PyModule_AddObjectRef(m, "Entry", (PyObject *)&EntryType) < 0 ||
        PyModule_AddObjectRef(m, "PlainDistance", (PyObject *)&PlainType) < 0 ||
        PyModule_AddObjectRef(m, "PairQuery", (PyObject *)&PairQueryType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
