"""Fast CDR (XCDR1, little endian) serialisation of the DDS backend's message classes.

``cyclonedds``' generic Python serialiser interprets the type for every sample (about 30 us for a
``UHState``); the stack exchanges tens of messages per 10 ms step across many processes, so the
backend's publishers and subscriptions use codecs generated here once per type instead: straight
``struct.pack``/``unpack_from`` calls over runs of fixed-size fields, with the CDR alignment
worked out when the code is generated wherever it is known (a few microseconds per message).

The codecs are built from the same rosbags type definitions as the classes
(:mod:`uh_runtime.messages`) and produce the same bytes as ``IdlStruct.serialize()`` and rosbags'
``serialize_cdr`` (tests/test_messages.py checks all three) and read what rosbags' ``deserialize_cdr``
reads (tests/test_cdr_codec.py, random messages of every uh_msgs type). This is the project's one CDR
reader besides rosbags'; the report's :mod:`uh_report.cdr_columns` holds no CDR rule (it reads numeric
fields at the offsets rosbags' own encoder gives them). Rules (OMG CDR / XCDR1, as ROS 2):
a primitive is aligned to its size (8 for 64-bit) relative to the start of the payload after the
4-byte encapsulation header; a string is a uint32 length including the terminating NUL, the bytes
and the NUL; a sequence is a uint32 count and its elements; a fixed array is its elements.
Payloads that are not little-endian XCDR1 are handed to ``cyclonedds``' own deserialiser.
"""
import struct
import threading

from rosbags.typesys.base import Nodetype

from .. import messages

__all__ = ['codec', 'Codec']

_FMT = {'bool': ('?', 1), 'byte': ('B', 1), 'char': ('B', 1), 'int8': ('b', 1),
        'uint8': ('B', 1), 'int16': ('h', 2), 'uint16': ('H', 2), 'int32': ('i', 4),
        'uint32': ('I', 4), 'int64': ('q', 8), 'uint64': ('Q', 8), 'float32': ('f', 4),
        'float64': ('d', 8)}
_PAD = [b'\0' * n for n in range(8)]
_HEADER = b'\x00\x01\x00\x00'



def _align(size, out, ind, run, al, flush, runtime_line):
    """Align the generated code to ``size`` bytes: padding in the pending ``run`` where the offset is known.

    Where the offset is only known at run time, ``flush`` emits the pending run and ``runtime_line``
    (the serialiser's or the deserialiser's padding statement) is added at indentation ``ind``.
    """
    pad = al.pad_for(size)
    if pad is None:
        flush(run, out, ind)
        out.append('    ' * ind + runtime_line)
        al.aligned(size)
        return
    if pad:
        run['fmt'] += 'x' * pad
        al.advance(pad)

class Codec:
    """``serialize(msg) -> bytes`` (with the 4-byte header) and ``deserialize(data) -> msg``.

    ``source`` is the Python source generated for the type (kept for debugging).
    """

    __slots__ = ('serialize', 'deserialize', 'source')

    def __init__(self, serialize, deserialize, source):
        self.serialize = serialize
        self.deserialize = deserialize
        self.source = source


class _Alignment:
    """What is known statically about the payload offset: offset = rem (mod mod)."""

    def __init__(self, mod=8, rem=0):
        self.mod, self.rem = mod, rem

    def pad_for(self, size):
        """Return the static padding before an item of alignment ``size``, or None if not known."""
        if size <= self.mod:
            return (-self.rem) % size
        return None

    def advance(self, nbytes):
        self.rem = (self.rem + nbytes) % self.mod

    def aligned(self, size):
        self.mod, self.rem = size, 0

    def unknown(self):
        self.mod, self.rem = 1, 0


class _Gen:
    """Generates the source of the serialiser and deserialiser functions of one type."""

    def __init__(self, store, classes):
        self.store = store
        self.classes = classes           # ros type name -> class
        self.functions = {}              # ros type name -> function base name
        self.lines = []
        self.counter = 0

    def var(self, prefix='v'):
        self.counter += 1
        return f'{prefix}{self.counter}'

    def fname(self, typename):
        return 'T_' + typename.replace('/', '_')

    # ------------------------------------------------------------------ serialiser
    def ser_function(self, typename, top=False):
        """Emit ``_s_<T>(m, b)`` appending ``m``; return its name.

        ``m`` is appended at payload offset 0 if ``top``, else at an unknown offset.
        """
        name = f"_s{'top' if top else ''}_{self.fname(typename)}"
        if name in self.functions:
            return name
        self.functions[name] = True
        body = []
        self._ser_body(typename, 'm', body, _Alignment(8, 0) if top else _Alignment(1, 0), 1)
        self.lines += [f'def {name}(m, b):'] + (body or ['    pass']) + ['']
        return name

    def _flush(self, run, out, ind):
        if run['fmt']:
            out.append(f"{'    ' * ind}b += _pack('<{run['fmt']}', {', '.join(run['args'])})")
        run['fmt'], run['args'] = '', []

    def _align_runtime(self, size, out, ind, run, al):
        _align(size, out, ind, run, al, self._flush, f"b += _PAD[(4 - len(b)) % {size}]")

    def _ser_body(self, typename, expr, out, al, ind, run=None):
        top = run is None
        run = run if run is not None else {'fmt': '', 'args': []}
        _, fields = self.store.fielddefs[typename]
        for fname, spec in fields:
            self._ser_field(spec, f'{expr}.{fname}', out, al, ind, run)
        if top:
            self._flush(run, out, ind)

    def _ser_field(self, spec, expr, out, al, ind, run):
        kind, details = spec
        pad = '    ' * ind
        if kind == Nodetype.BASE:
            base = details[0]
            if base == 'string':
                self._align_runtime(4, out, ind, run, al)
                self._flush(run, out, ind)
                s = self.var('s')
                out.append(f'{pad}{s} = {expr}.encode()')
                out.append(f'{pad}b += _pack("<I", len({s}) + 1)')
                out.append(f'{pad}b += {s}')
                out.append(f"{pad}b += b'\\0'")
                al.unknown()
                return
            if base not in _FMT:
                raise TypeError(f'CDR codec: primitive {base!r} is not supported')
            code, size = _FMT[base]
            self._align_runtime(size, out, ind, run, al)
            run['fmt'] += code
            run['args'].append(expr)
            al.advance(size)
            return
        if kind == Nodetype.NAME:
            self._ser_body(details, expr, out, al, ind, run)
            return
        sub, length = details
        sub_kind, sub_details = sub
        if kind == Nodetype.SEQUENCE:
            self._align_runtime(4, out, ind, run, al)
            self._flush(run, out, ind)
            seq = self.var('q')
            out.append(f'{pad}{seq} = {expr}')
            out.append(f'{pad}b += _pack("<I", len({seq}))')
            al.advance(4)
            count = f'len({seq})'
        else:
            seq = None
            count = str(length)
        if sub_kind == Nodetype.BASE and sub_details[0] in _FMT:
            code, size = _FMT[sub_details[0]]
            if kind == Nodetype.ARRAY:
                self._align_runtime(size, out, ind, run, al)
                if size == 1 and code == 'B':
                    self._flush(run, out, ind)
                    out.append(f'{pad}b += bytes({expr})')
                else:
                    run['fmt'] += f'{length}{code}'
                    run['args'].append(f'*{expr}')
                al.advance(size * length)
                return
            # sequence of primitives: elements aligned only if there are any
            out.append(f'{pad}if {seq}:')
            if size > 1 and al.pad_for(size) is None:
                out.append(f'{pad}    b += _PAD[(4 - len(b)) % {size}]')
            elif size > 1 and al.pad_for(size):
                out.append(f'{pad}    b += _PAD[{al.pad_for(size)}]')
            if code == 'B':
                out.append(f'{pad}    b += bytes({seq})')
            else:
                out.append(f"{pad}    b += _pack('<%d{code}' % {count}, *{seq})")
            if size >= 4:
                al.aligned(4)
            else:
                al.unknown()
            return
        # strings or messages: a loop
        self._flush(run, out, ind)
        item = self.var('e')
        out.append(f'{pad}for {item} in {seq or expr}:')
        if sub_kind == Nodetype.NAME:
            out.append(f'{pad}    {self.ser_function(sub_details)}({item}, b)')
        else:  # strings
            s = self.var('s')
            out.append(f'{pad}    b += _PAD[(4 - len(b)) % 4]')
            out.append(f'{pad}    {s} = {item}.encode()')
            out.append(f'{pad}    b += _pack("<I", len({s}) + 1)')
            out.append(f'{pad}    b += {s}')
            out.append(f"{pad}    b += b'\\0'")
        al.unknown()

    # ------------------------------------------------------------------ deserialiser
    def de_function(self, typename, top=False):
        """Emit ``_d_<T>(d, p) -> (msg, p)``; return its name.

        The emitted function reads at payload offset 0 if ``top``, else at an unknown offset.
        """
        name = f"_d{'top' if top else ''}_{self.fname(typename)}"
        if name in self.functions:
            return name
        self.functions[name] = True
        body = []
        run = {'fmt': '', 'vars': []}
        result = self._de_body(typename, body, _Alignment(8, 0) if top else _Alignment(1, 0), 1, run)
        self._dflush(run, body, 1)
        self.lines += [f'def {name}(d, p):'] + body + [f'    return {result}, p', '']
        return name

    def _dflush(self, run, out, ind):
        if run['fmt']:
            pad = '    ' * ind
            names = ', '.join(run['vars'])
            fmt = '<' + run['fmt']
            out.append(f'{pad}{names}{"," if len(run["vars"]) == 1 else ""} = _unpack_from({fmt!r}, d, p)')
            out.append(f'{pad}p += {struct.calcsize(fmt)}')
        run['fmt'], run['vars'] = '', []

    def _dalign(self, size, out, ind, run, al):
        _align(size, out, ind, run, al, self._dflush, f"p += (4 - p) % {size}")

    def _de_body(self, typename, out, al, ind, run):
        """Emit reads of every field; return the constructor expression of the message."""
        _, fields = self.store.fielddefs[typename]
        args = [self._de_field(spec, out, al, ind, run) for _, spec in fields]
        cls = self.fname(typename)
        self.classes_used.add(typename)
        return f'{cls}({", ".join(args)})'

    def _de_field(self, spec, out, al, ind, run):
        kind, details = spec
        pad = '    ' * ind
        if kind == Nodetype.BASE:
            base = details[0]
            if base == 'string':
                self._dalign(4, out, ind, run, al)
                self._dflush(run, out, ind)
                n, s = self.var('n'), self.var('s')
                out.append(f'{pad}{n}, = _unpack_from("<I", d, p)')
                out.append(f"{pad}{s} = d[p + 4:p + 3 + {n}].decode() if {n} else ''")
                out.append(f'{pad}p += 4 + {n}')
                al.unknown()
                return s
            code, size = _FMT[base]
            self._dalign(size, out, ind, run, al)
            v = self.var()
            run['fmt'] += code
            run['vars'].append(v)
            al.advance(size)
            return v
        if kind == Nodetype.NAME:
            return self._de_body(details, out, al, ind, run)
        sub, length = details
        sub_kind, sub_details = sub
        if kind == Nodetype.SEQUENCE:
            self._dalign(4, out, ind, run, al)
            self._dflush(run, out, ind)
            count = self.var('c')
            out.append(f'{pad}{count}, = _unpack_from("<I", d, p)')
            out.append(f'{pad}p += 4')
            al.advance(4)
        else:
            count = str(length)
        v = self.var('a')
        if sub_kind == Nodetype.BASE and sub_details[0] in _FMT:
            code, size = _FMT[sub_details[0]]
            if kind == Nodetype.ARRAY:
                self._dalign(size, out, ind, run, al)
                self._dflush(run, out, ind)
                out.append(f"{pad}{v} = list(_unpack_from('<{length}{code}', d, p))")
                out.append(f'{pad}p += {size * length}')
                al.advance(size * length)
                return v
            out.append(f'{pad}if {count}:')
            if size > 1 and al.pad_for(size) is None:
                out.append(f'{pad}    p += (4 - p) % {size}')
            elif size > 1 and al.pad_for(size):
                out.append(f'{pad}    p += {al.pad_for(size)}')
            out.append(f"{pad}    {v} = list(_unpack_from('<%d{code}' % {count}, d, p))")
            out.append(f'{pad}    p += {size} * {count}')
            out.append(f'{pad}else:')
            out.append(f'{pad}    {v} = []')
            if size >= 4:
                al.aligned(4)
            else:
                al.unknown()
            return v
        self._dflush(run, out, ind)
        out.append(f'{pad}{v} = []')
        out.append(f'{pad}for _ in range({count}):')
        if sub_kind == Nodetype.NAME:
            e = self.var('e')
            out.append(f'{pad}    {e}, p = {self.de_function(sub_details)}(d, p)')
            out.append(f'{pad}    {v}.append({e})')
        else:
            n = self.var('n')
            out.append(f'{pad}    p += (4 - p) % 4')
            out.append(f'{pad}    {n}, = _unpack_from("<I", d, p)')
            out.append(f"{pad}    {v}.append(d[p + 4:p + 3 + {n}].decode() if {n} else '')")
            out.append(f'{pad}    p += 4 + {n}')
        al.unknown()
        return v


_lock = threading.Lock()
_codecs = {}


def codec(cls) -> Codec:
    """Return the (cached) codec of a DDS backend message class (``__ros_typename__`` set)."""
    typename = cls.__ros_typename__
    found = _codecs.get(typename)
    if found is not None:
        return found
    with _lock:
        if typename in _codecs:
            return _codecs[typename]
        gen = _Gen(messages.typestore(), {})
        gen.classes_used = set()
        ser = gen.ser_function(typename, top=True)
        de = gen.de_function(typename, top=True)
        source = '\n'.join(gen.lines)
        namespace = {'_pack': struct.pack, '_unpack_from': struct.unpack_from, '_PAD': _PAD}
        for used in gen.classes_used | {typename}:
            namespace[gen.fname(used)] = messages.dds_message(used)
        exec(compile(source, f'<cdr codec {typename}>', 'exec'), namespace)
        ser_fn, de_fn = namespace[ser], namespace[de]
        fallback = cls.deserialize

        def serialize(msg, _ser=ser_fn, _header=_HEADER):
            b = bytearray(_header)
            try:
                _ser(msg, b)
            except (struct.error, AttributeError, TypeError, UnicodeError) as exc:
                raise TypeError(f'cannot serialise {typename}: {exc}; check the field values '
                                '(types and ranges of the .msg definition)') from None
            return bytes(b)

        def deserialize(data, _de=de_fn):
            if data[:2] != b'\x00\x01':     # not little-endian XCDR1: the generic reader
                return fallback(bytes(data))
            return _de(data, 4)[0]

        result = Codec(serialize, deserialize, source)
        _codecs[typename] = result
        return result
