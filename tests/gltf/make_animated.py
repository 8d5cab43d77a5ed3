#!/usr/bin/env python3
"""Generate the animated glTF 2.0 test scenes for Tessera's animation support.

    python3 tests/gltf/make_animated.py OUTDIR [--crowd N]

Writes into OUTDIR (created if missing), each as NAME.gltf plus NAME.bin (the buffer's uri is
the relative name NAME.bin), byte-for-byte deterministic:

  skinned_cylinder  a cylinder along +Y (y 0..2, radius 0.25) skinned to two joints, bone0 and
                    bone1 (at y=1); animation "bend" turns bone1 about +Z by 0, 90, 0 degrees at
                    t = 0, 1, 2 s. Skinning in Tessera's animation render tests.
  morph_cube        a unit cube with two morph targets (0: the top grows up by 1; 1: the top edge
                    of the +X side moves out by 0.5, tilting two faces); animation "morph" drives
                    the weights [0,0] -> [1,0] -> [0,1].
                    Morph targets in the animation render tests.
  trs_nodes         three cubes animated by node TRS channels with each interpolation: LINEAR
                    translation and rotation (node "linear"), STEP translation and LINEAR scale
                    (node "step"), CUBICSPLINE translation (node "cubic"). Interpolation modes in
                    the animation render tests and the farm test.
  camera_light      a box on a floor seen by an animated camera and lit by an animated point
                    light (animation "fly"): file cameras and lights on animated nodes.
  crowd             N instances (--crowd, default 100) of the skinned cylinder in a grid, each
                    with its own skeleton and skin, all in one animation "wave" with phase-shifted
                    bends. The skinned-crowd benchmark.

Standard library only. Floats go into the buffer as little-endian float32; accessor min/max are
the float32 values of the data, as the validator compares them.
"""

import argparse
import json
import math
import os
import struct

# glTF constants.
BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
COMPONENT_FORMAT = {BYTE: 'b', UNSIGNED_BYTE: 'B', SHORT: 'h', UNSIGNED_SHORT: 'H',
                    UNSIGNED_INT: 'I', FLOAT: 'f'}
TYPE_COMPONENTS = {'SCALAR': 1, 'VEC2': 2, 'VEC3': 3, 'VEC4': 4, 'MAT4': 16}

GENERATOR = 'Tessera tests/gltf/make_animated.py'


def f32(x):
    """The value x has once stored as float32 (what min/max must hold)."""
    return struct.unpack('<f', struct.pack('<f', x))[0]


class Builder:
    """Appends typed data to one binary buffer (each piece 4-byte aligned, in its own
    bufferView) and makes the glTF bufferViews and accessors for it."""

    def __init__(self):
        self.data = bytearray()
        self.buffer_views = []
        self.accessors = []

    def _align(self):
        while len(self.data) % 4:
            self.data.append(0)

    def view(self, blob, target=None):
        self._align()
        view = {'buffer': 0, 'byteOffset': len(self.data), 'byteLength': len(blob)}
        if target is not None:
            view['target'] = target
        self.data += blob
        self.buffer_views.append(view)
        return len(self.buffer_views) - 1

    def accessor(self, elements, component_type, type_, target=None, minmax=False,
                 normalized=False):
        """elements: a list of numbers (SCALAR) or of tuples with the type's component count.
        Returns the accessor's index."""
        n = TYPE_COMPONENTS[type_]
        rows = [tuple(e) if isinstance(e, (tuple, list)) else (e,) for e in elements]
        assert rows, 'an accessor needs at least one element'
        for r in rows:
            assert len(r) == n, (type_, r)
        flat = [c for r in rows for c in r]
        fmt = COMPONENT_FORMAT[component_type]
        blob = struct.pack('<%d%s' % (len(flat), fmt), *flat)
        acc = {'bufferView': self.view(blob, target), 'componentType': component_type,
               'count': len(rows), 'type': type_}
        if normalized:
            acc['normalized'] = True
        if minmax:
            stored = [tuple(f32(c) for c in r) for r in rows] if component_type == FLOAT else rows
            acc['min'] = [min(r[k] for r in stored) for k in range(n)]
            acc['max'] = [max(r[k] for r in stored) for k in range(n)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def finish(self, gltf, name):
        """Puts the buffer, bufferViews and accessors into gltf; returns the .bin bytes."""
        self._align()
        gltf['buffers'] = [{'uri': name + '.bin', 'byteLength': len(self.data)}]
        gltf['bufferViews'] = self.buffer_views
        gltf['accessors'] = self.accessors
        return bytes(self.data)


# ---------------------------------------------------------------------------------------------
# Math helpers.

def quat_axis_angle(axis, degrees):
    """Unit quaternion (x, y, z, w) for a rotation of degrees about the unit axis."""
    half = math.radians(degrees) / 2.0
    s = math.sin(half)
    q = (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(half))
    norm = math.sqrt(sum(c * c for c in q))
    return tuple(c / norm + 0.0 for c in q)  # + 0.0: no -0.0


def mat4_translation(t):
    """Column-major 4x4 translation matrix as 16 floats."""
    return (1.0, 0.0, 0.0, 0.0,
            0.0, 1.0, 0.0, 0.0,
            0.0, 0.0, 1.0, 0.0,
            t[0] + 0.0, t[1] + 0.0, t[2] + 0.0, 1.0)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def check_ccw(positions, normals, indices):
    """Each triangle's geometric normal (CCW) points along its vertices' normals (outside)."""
    for t in range(0, len(indices), 3):
        a, b, c = (positions[i] for i in indices[t:t + 3])
        n = cross(sub(b, a), sub(c, a))
        assert dot(n, normals[indices[t]]) > 0, 'triangle %d is not CCW from outside' % (t // 3)


# ---------------------------------------------------------------------------------------------
# Geometry.

CYL_RADIUS = 0.25
CYL_SEGMENTS = 16
CYL_RINGS = 9          # y = 0, 0.25, ..., 2.0
CYL_HEIGHT = 2.0


def cylinder_geometry():
    """Side surface of the cylinder: (positions, normals, uvs, joints, weights, indices).
    Each ring has CYL_SEGMENTS + 1 vertices (the seam is duplicated for the texture
    coordinates). x = r sin(theta), z = r cos(theta), so (s, r), (s+1, r), (s+1, r+1) is CCW
    seen from outside."""
    positions, normals, uvs, joints, weights = [], [], [], [], []
    for ring in range(CYL_RINGS):
        y = CYL_HEIGHT * ring / (CYL_RINGS - 1)
        w1 = min(max((y - 0.5) / 1.0, 0.0), 1.0)
        w0 = 1.0 - w1
        # A joint slot with zero weight names joint 0 (so bone1's slot is 0 while w1 is 0).
        j = (0, 1 if w1 > 0.0 else 0, 0, 0)
        for s in range(CYL_SEGMENTS + 1):
            theta = 2.0 * math.pi * (s % CYL_SEGMENTS) / CYL_SEGMENTS
            sn, cs = math.sin(theta), math.cos(theta)
            positions.append((CYL_RADIUS * sn, y, CYL_RADIUS * cs))
            normals.append((sn, 0.0, cs))
            uvs.append((s / CYL_SEGMENTS, 1.0 - y / CYL_HEIGHT))
            joints.append(j)
            weights.append((w0, w1, 0.0, 0.0))
    indices = []
    row = CYL_SEGMENTS + 1
    for ring in range(CYL_RINGS - 1):
        for s in range(CYL_SEGMENTS):
            a = ring * row + s
            b, c, d = a + 1, a + 1 + row, a + row
            indices += [a, b, c, a, c, d]
    check_ccw(positions, normals, indices)
    for w in weights:
        assert abs(sum(f32(c) for c in w) - 1.0) <= 1e-6
    return positions, normals, uvs, joints, weights, indices


# Faces of the cube: (normal, u, v) with u x v = normal, so the corners -u-v, +u-v, +u+v, -u+v
# run CCW seen from outside.
CUBE_FACES = [
    ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
    ((0, 1, 0), (0, 0, 1), (1, 0, 0)),
    ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
    ((0, 0, -1), (0, 1, 0), (1, 0, 0)),
]


def cube_geometry():
    """Cube from -0.5 to 0.5: 24 vertices (4 per face, flat normals), 36 indices."""
    positions, normals, indices = [], [], []
    for n, u, v in CUBE_FACES:
        assert cross(u, v) == n
        base = len(positions)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            positions.append(tuple(0.5 * (n[k] + su * u[k] + sv * v[k]) for k in range(3)))
            normals.append(tuple(float(c) for c in n))
        indices += [base, base + 1, base + 2, base, base + 2, base + 3]
    check_ccw(positions, normals, indices)
    assert len(positions) == 24 and len(indices) == 36
    return positions, normals, indices


def add_cylinder_primitive(b, material):
    positions, normals, uvs, joints, weights, indices = cylinder_geometry()
    return {
        'attributes': {
            'POSITION': b.accessor(positions, FLOAT, 'VEC3', ARRAY_BUFFER, minmax=True),
            'NORMAL': b.accessor(normals, FLOAT, 'VEC3', ARRAY_BUFFER),
            'TEXCOORD_0': b.accessor(uvs, FLOAT, 'VEC2', ARRAY_BUFFER),
            'JOINTS_0': b.accessor(joints, UNSIGNED_BYTE, 'VEC4', ARRAY_BUFFER),
            'WEIGHTS_0': b.accessor(weights, FLOAT, 'VEC4', ARRAY_BUFFER),
        },
        'indices': b.accessor(indices, UNSIGNED_SHORT, 'SCALAR', ELEMENT_ARRAY_BUFFER),
        'material': material,
        'mode': 4,
    }


def material(name, rgb, roughness):
    return {'name': name,
            'pbrMetallicRoughness': {'baseColorFactor': [rgb[0], rgb[1], rgb[2], 1.0],
                                     'metallicFactor': 0.0, 'roughnessFactor': roughness},
            'doubleSided': False}


ORANGE = material('orange', (0.9, 0.45, 0.1), 0.5)


def times(b, ts):
    """An animation input accessor (min/max are required there)."""
    return b.accessor(ts, FLOAT, 'SCALAR', minmax=True)


def asset():
    return {'asset': {'version': '2.0', 'generator': GENERATOR}}


# ---------------------------------------------------------------------------------------------
# The scenes. Each returns (gltf dict, bin bytes).

def skinned_cylinder():
    name = 'skinned_cylinder'
    b = Builder()
    g = asset()
    g['scene'] = 0
    g['scenes'] = [{'name': name, 'nodes': [0, 2]}]
    g['nodes'] = [
        {'name': 'bone0', 'children': [1]},
        {'name': 'bone1', 'translation': [0.0, 1.0, 0.0]},
        {'name': 'cylinder', 'mesh': 0, 'skin': 0},
    ]
    g['materials'] = [ORANGE]
    g['meshes'] = [{'name': 'cylinder', 'primitives': [add_cylinder_primitive(b, 0)]}]
    ibm = b.accessor([mat4_translation((0, 0, 0)), mat4_translation((0, -1, 0))], FLOAT, 'MAT4')
    g['skins'] = [{'name': 'cylinder_skin', 'joints': [0, 1], 'inverseBindMatrices': ibm}]
    z = (0.0, 0.0, 1.0)
    g['animations'] = [{
        'name': 'bend',
        'channels': [{'sampler': 0, 'target': {'node': 1, 'path': 'rotation'}}],
        'samplers': [{'input': times(b, [0.0, 1.0, 2.0]), 'interpolation': 'LINEAR',
                      'output': b.accessor([quat_axis_angle(z, a) for a in (0, 90, 0)],
                                           FLOAT, 'VEC4')}],
    }]
    return name, g, b.finish(g, name)


def morph_cube():
    name = 'morph_cube'
    b = Builder()
    positions, normals, indices = cube_geometry()
    target0 = [(0.0, 1.0, 0.0) if p[1] > 0 else (0.0, 0.0, 0.0) for p in positions]
    # The top edge of the +X side leans out: the +X and top faces tilt (their normals turn).
    target1 = [(0.5, 0.0, 0.0) if p[0] > 0 and p[1] > 0 else (0.0, 0.0, 0.0) for p in positions]
    g = asset()
    g['scene'] = 0
    g['scenes'] = [{'name': name, 'nodes': [0]}]
    g['nodes'] = [{'name': 'cube', 'mesh': 0}]
    g['materials'] = [material('blue', (0.2, 0.5, 0.9), 0.6)]
    g['meshes'] = [{
        'name': 'cube',
        'primitives': [{
            'attributes': {
                'POSITION': b.accessor(positions, FLOAT, 'VEC3', ARRAY_BUFFER, minmax=True),
                'NORMAL': b.accessor(normals, FLOAT, 'VEC3', ARRAY_BUFFER),
            },
            'indices': b.accessor(indices, UNSIGNED_SHORT, 'SCALAR', ELEMENT_ARRAY_BUFFER),
            'material': 0,
            'mode': 4,
            'targets': [
                {'POSITION': b.accessor(target0, FLOAT, 'VEC3', ARRAY_BUFFER, minmax=True)},
                {'POSITION': b.accessor(target1, FLOAT, 'VEC3', ARRAY_BUFFER, minmax=True)},
            ],
        }],
        'weights': [0.0, 0.0],
        'extras': {'targetNames': ['top_up', 'right_leans_out']},
    }]
    g['animations'] = [{
        'name': 'morph',
        'channels': [{'sampler': 0, 'target': {'node': 0, 'path': 'weights'}}],
        'samplers': [{'input': times(b, [0.0, 1.0, 2.0]), 'interpolation': 'LINEAR',
                      'output': b.accessor([0.0, 0.0, 1.0, 0.0, 0.0, 1.0], FLOAT, 'SCALAR')}],
    }]
    return name, g, b.finish(g, name)


def trs_nodes():
    name = 'trs_nodes'
    b = Builder()
    positions, normals, indices = cube_geometry()
    attributes = {
        'POSITION': b.accessor(positions, FLOAT, 'VEC3', ARRAY_BUFFER, minmax=True),
        'NORMAL': b.accessor(normals, FLOAT, 'VEC3', ARRAY_BUFFER),
    }
    index_acc = b.accessor(indices, UNSIGNED_SHORT, 'SCALAR', ELEMENT_ARRAY_BUFFER)
    colours = [('red', (0.9, 0.15, 0.1)), ('green', (0.15, 0.8, 0.2)), ('blue', (0.15, 0.3, 0.9))]
    g = asset()
    g['scene'] = 0
    g['scenes'] = [{'name': name, 'nodes': [0, 1, 2]}]
    g['nodes'] = [
        {'name': 'linear', 'mesh': 0, 'translation': [-2.0, 0.0, 0.0]},
        {'name': 'step', 'mesh': 1, 'translation': [0.0, 0.0, 0.0]},
        {'name': 'cubic', 'mesh': 2, 'translation': [2.0, 0.0, 0.0]},
    ]
    g['materials'] = [material(c, rgb, 0.5) for c, rgb in colours]
    # Meshes cannot take a material per node: three meshes share the accessors.
    g['meshes'] = [{'name': 'cube_' + c,
                    'primitives': [{'attributes': dict(attributes), 'indices': index_acc,
                                    'material': m, 'mode': 4}]}
                   for m, (c, _) in enumerate(colours)]
    t01 = times(b, [0.0, 1.0])
    y = (0.0, 1.0, 0.0)
    samplers = [
        # (a) node 0 translation, LINEAR
        {'input': t01, 'interpolation': 'LINEAR',
         'output': b.accessor([(-2.0, 0.0, 0.0), (-2.0, 1.0, 0.0)], FLOAT, 'VEC3')},
        # (b) node 0 rotation, LINEAR: 0 and 90 degrees about +Y
        {'input': t01, 'interpolation': 'LINEAR',
         'output': b.accessor([quat_axis_angle(y, 0), quat_axis_angle(y, 90)], FLOAT, 'VEC4')},
        # (c) node 1 translation, STEP
        {'input': times(b, [0.0, 0.5, 1.0]), 'interpolation': 'STEP',
         'output': b.accessor([(0.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.5, 0.0)],
                              FLOAT, 'VEC3')},
        # (d) node 2 translation, CUBICSPLINE: per key in-tangent, value, out-tangent
        {'input': t01, 'interpolation': 'CUBICSPLINE',
         'output': b.accessor([(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 0.0),
                               (0.0, 0.0, 0.0), (2.0, 1.0, 0.0), (0.0, 0.0, 0.0)],
                              FLOAT, 'VEC3')},
        # (e) node 1 scale, LINEAR
        {'input': t01, 'interpolation': 'LINEAR',
         'output': b.accessor([(1.0, 1.0, 1.0), (0.5, 2.0, 0.5)], FLOAT, 'VEC3')},
    ]
    targets = [(0, 'translation'), (0, 'rotation'), (1, 'translation'), (2, 'translation'),
               (1, 'scale')]
    g['animations'] = [{
        'name': 'move',
        'channels': [{'sampler': i, 'target': {'node': node, 'path': path}}
                     for i, (node, path) in enumerate(targets)],
        'samplers': samplers,
    }]
    return name, g, b.finish(g, name)


def camera_light():
    """A box on a floor, seen by an animated camera and lit by an animated point light."""
    name = 'camera_light'
    b = Builder()
    positions, normals, indices = cube_geometry()
    mesh = {'primitives': [{
        'attributes': {
            'POSITION': b.accessor(positions, FLOAT, 'VEC3', ARRAY_BUFFER, minmax=True),
            'NORMAL': b.accessor(normals, FLOAT, 'VEC3', ARRAY_BUFFER)},
        'indices': b.accessor(indices, UNSIGNED_SHORT, 'SCALAR', ELEMENT_ARRAY_BUFFER),
        'material': 0, 'mode': 4}]}
    g = asset()
    g['extensionsUsed'] = ['KHR_lights_punctual']
    g['extensions'] = {'KHR_lights_punctual': {'lights': [
        {'name': 'lamp', 'type': 'point', 'color': [1.0, 0.9, 0.8], 'intensity': 30.0}]}}
    g['scene'] = 0
    g['scenes'] = [{'name': name, 'nodes': [0, 1, 2, 3]}]
    g['nodes'] = [
        {'name': 'floor', 'mesh': 0, 'translation': [0.0, -0.6, 0.0], 'scale': [8.0, 0.2, 8.0]},
        {'name': 'box', 'mesh': 0},
        {'name': 'camera', 'camera': 0, 'translation': [0.0, 1.0, 6.0]},
        {'name': 'lamp', 'translation': [-2.0, 2.0, 1.0],
         'extensions': {'KHR_lights_punctual': {'light': 0}}},
    ]
    g['cameras'] = [{'name': 'fly', 'type': 'perspective',
                     'perspective': {'yfov': 0.8, 'znear': 0.1, 'aspectRatio': 1.5}}]
    g['materials'] = [material('grey', (0.7, 0.7, 0.7), 0.6)]
    g['meshes'] = [mesh]
    t02 = times(b, [0.0, 2.0])
    g['animations'] = [{
        'name': 'fly',
        'samplers': [
            # The camera slides from x = -3 to 3 (looking down -Z), the lamp from x = -2 to 2.
            {'input': t02, 'interpolation': 'LINEAR',
             'output': b.accessor([(-3.0, 1.0, 6.0), (3.0, 1.0, 6.0)], FLOAT, 'VEC3')},
            {'input': t02, 'interpolation': 'LINEAR',
             'output': b.accessor([(-2.0, 2.0, 1.0), (2.0, 2.0, 1.0)], FLOAT, 'VEC3')},
        ],
        'channels': [{'sampler': 0, 'target': {'node': 2, 'path': 'translation'}},
                     {'sampler': 1, 'target': {'node': 3, 'path': 'translation'}}],
    }]
    return name, g, b.finish(g, name)


def crowd(n):
    name = 'crowd'
    b = Builder()
    cols = math.isqrt(n)
    if cols * cols < n:
        cols += 1
    rows = -(-n // cols)
    g = asset()
    g['scene'] = 0
    g['materials'] = [ORANGE]
    g['meshes'] = [{'name': 'cylinder', 'primitives': [add_cylinder_primitive(b, 0)]}]
    nodes, skins = [], []
    key_times = [0.25 * k for k in range(9)]  # 0, 0.25, ..., 2.0
    t_acc = times(b, key_times)
    channels, samplers = [], []
    z = (0.0, 0.0, 1.0)
    ibm = b.accessor([mat4_translation((0, 0, 0)), mat4_translation((0, -1, 0))], FLOAT, 'MAT4')
    for i in range(n):
        col, row = i % cols, i // cols
        p = ((col - (cols - 1) / 2.0) * 1.0 + 0.0, 0.0, (row - (rows - 1) / 2.0) * 1.0 + 0.0)
        root, bone1, body = 3 * i, 3 * i + 1, 3 * i + 2
        nodes += [
            {'name': 'root_%d' % i, 'translation': list(p), 'children': [bone1]},
            {'name': 'bone1_%d' % i, 'translation': [0.0, 1.0, 0.0]},
            {'name': 'body_%d' % i, 'mesh': 0, 'skin': i},
        ]
        # The shared mesh is bound at the origin, in its skeleton's space: the inverse bind
        # matrices are the single cylinder's, and each root joint places its instance at P_i.
        skins.append({'name': 'skin_%d' % i, 'joints': [root, bone1],
                      'inverseBindMatrices': ibm})
        quats = [quat_axis_angle(z, 60.0 * math.sin(2.0 * math.pi * (t / 2.0 + i / n)))
                 for t in key_times]
        samplers.append({'input': t_acc, 'interpolation': 'LINEAR',
                         'output': b.accessor(quats, FLOAT, 'VEC4')})
        channels.append({'sampler': i, 'target': {'node': bone1, 'path': 'rotation'}})
    g['scenes'] = [{'name': name,
                    'nodes': [3 * i for i in range(n)] + [3 * i + 2 for i in range(n)]}]
    g['nodes'] = nodes
    g['skins'] = skins
    g['animations'] = [{'name': 'wave', 'channels': channels, 'samplers': samplers}]
    return name, g, b.finish(g, name)


# ---------------------------------------------------------------------------------------------

def write(outdir, name, gltf, blob):
    gltf_path = os.path.join(outdir, name + '.gltf')
    bin_path = os.path.join(outdir, name + '.bin')
    with open(bin_path, 'wb') as f:
        f.write(blob)
    with open(gltf_path, 'wb') as f:
        f.write((json.dumps(gltf, indent=1) + '\n').encode('utf-8'))
    return gltf_path, bin_path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('outdir')
    ap.add_argument('--crowd', type=int, default=100, metavar='N',
                    help='instances in crowd.gltf (default 100)')
    args = ap.parse_args()
    if args.crowd < 1:
        ap.error('--crowd must be at least 1')
    os.makedirs(args.outdir, exist_ok=True)
    for name, gltf, blob in (skinned_cylinder(), morph_cube(), trs_nodes(), camera_light(),
                             crowd(args.crowd)):
        gltf_path, _ = write(args.outdir, name, gltf, blob)
        print('%s: %d nodes, %d accessors, %d-byte %s.bin'
              % (gltf_path, len(gltf['nodes']), len(gltf['accessors']), len(blob), name))


if __name__ == '__main__':
    main()
