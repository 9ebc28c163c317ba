# Writes the MAT v5 seeds of mat_record_fuzz (tests/fuzz/corpus/mat_record_fuzz) without numpy, per
# MathWorks' "MAT-File Format": a record as top-level vectors with a text and a short vector to
# skip, and one as a compressed 1x1 struct. Usage: python3 tests/fuzz/make_mat_seeds.py OUT_DIR
import math, struct, sys, zlib
miINT8, miINT32, miUINT32, miDOUBLE, miMATRIX, miCOMPRESSED = 1, 5, 6, 9, 14, 15
def pad8(b): return b + b'\0' * (-len(b) % 8)
def elem(t, payload):
    if len(payload) <= 4 and t != miMATRIX:  # small data element
        return struct.pack('<HH', t, len(payload)) + payload.ljust(4, b'\0')
    return struct.pack('<II', t, len(payload)) + pad8(payload)
def matrix(name, cls, dims, body):
    flags = elem(miUINT32, struct.pack('<II', cls, 0))
    d = elem(miINT32, struct.pack('<%di' % len(dims), *dims))
    n = elem(miINT8, name.encode())
    return elem(miMATRIX, flags + d + n + body)
def double_vec(name, values, column=True):
    dims = (len(values), 1) if column else (1, len(values))
    return matrix(name, 6, dims, elem(miDOUBLE, struct.pack('<%dd' % len(values), *values)))
def struct1(name, fields):
    width = 32
    names = b''.join(f.encode().ljust(width, b'\0') for f, _ in fields)
    body = elem(miINT32, struct.pack('<i', width)) + elem(miINT8, names)
    for f, v in fields: body += double_vec('', v)
    return matrix(name, 2, (1, 1), body)
def char(name, text):
    return matrix(name, 4, (1, len(text)), elem(4, struct.pack('<%dH' % len(text), *map(ord, text))))
def header():
    text = b'MATLAB 5.0 MAT-file, MillKit fuzz seed'.ljust(116, b' ')
    return text + b'\0' * 8 + struct.pack('<H', 0x0100) + b'IM'
def write(path, elements, compress=False):
    with open(path, 'wb') as f:
        f.write(header())
        for e in elements:
            f.write(elem(miCOMPRESSED, zlib.compress(e)) if compress else e)
out = sys.argv[1]
t = [k * 1e-3 for k in range(16)]
write(out + '/top_level.mat', [double_vec('time', t), double_vec('M1', [math.sin(300 * x) for x in t]),
                               char('note', 'kN*m'), double_vec('short', [1.0, 2.0], column=False)])
write(out + '/struct_compressed.mat',
      [struct1('rec', [('t', t), ('M2', [math.cos(300 * x) for x in t])])], compress=True)
