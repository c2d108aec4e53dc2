#!/usr/bin/env bash
# Regenerates the fuzzers' seed corpus (fuzz/corpus/<target>/) on purpose: small valid inputs of
# every reader (and a few near misses) for libFuzzer to mutate, and for the sanitized replay in
# the default test run. Run from the repository root after a build; commits the result by hand.
#
# Usage: scripts/make_fuzz_corpus.sh
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${SONICBOOM_BIN:-$ROOT/build/bin/sonicboom}
C=$ROOT/fuzz/corpus
rm -rf "$C"
mkdir -p "$C"/{wav,robot_log,npy,dataset,config}

# dataset: two kinematic strikes of 0.1 s records (a few tens of kB), complete and a partial copy
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$BIN" -q --set strike.engine=kinematic --set audio.record_duration_s=0.1 \
  --set audio.onset_time_s=0.05 --set audio.onset_jitter_s=0.01 --set strike.proprio_rows=5 \
  generate --count 2 --out "$tmp/d.h5" >/dev/null
# rewritten contiguous and uncompressed (the writer's 1024-row chunks make a 450 kB file of it)
/usr/bin/python3 - "$tmp/d.h5" "$C/dataset/two_strikes.h5" <<'PY'
import sys, h5py
src, dst = sys.argv[1], sys.argv[2]
with h5py.File(src, 'r') as a, h5py.File(dst, 'w') as b:
    for k, v in a.attrs.items():
        b.attrs[k] = v
    def copy(name, obj):
        if isinstance(obj, h5py.Dataset):
            d = b.create_dataset(name, data=obj[()], dtype=obj.dtype)
            for k, v in obj.attrs.items():
                d.attrs[k] = v
    a.visititems(copy)
PY

/usr/bin/python3 - "$C" <<'PY'
import io, struct, sys, wave
import numpy as np
import h5py
C = sys.argv[1]
rng = np.random.default_rng(1)

# WAV: 16-bit PCM and float, 6 channels and 1, a header with no frames
def pcm16(path, frames, channels, rate=44100):
    x = (rng.standard_normal((frames, channels)) * 2000).astype('<i2')
    with wave.open(path, 'wb') as w:
        w.setnchannels(channels); w.setsampwidth(2); w.setframerate(rate); w.writeframes(x.tobytes())
def float32(path, frames, channels, rate=44100):
    x = (rng.standard_normal((frames, channels)) * 0.1).astype('<f4').tobytes()
    fmt = struct.pack('<HHIIHH', 3, channels, rate, rate * channels * 4, channels * 4, 32)
    body = b'WAVE' + b'fmt ' + struct.pack('<I', 16) + fmt + b'data' + struct.pack('<I', len(x)) + x
    open(path, 'wb').write(b'RIFF' + struct.pack('<I', len(body)) + body)
pcm16(f'{C}/wav/pcm16_6ch.wav', 64, 6)
pcm16(f'{C}/wav/pcm16_mono.wav', 32, 1, 48000)
float32(f'{C}/wav/float_6ch.wav', 48, 6)
pcm16(f'{C}/wav/empty.wav', 0, 6)

# robot logs: the header and rows, LF and CRLF
header = 't_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s'
rows = ['%.2f,0.5,0.1,0.4,1,0,0,0,0.01,0,0' % (0.01 * k) for k in range(3)]
open(f'{C}/robot_log/three_rows.csv', 'w').write('\n'.join([header] + rows) + '\n')
open(f'{C}/robot_log/crlf.csv', 'w', newline='').write('\r\n'.join([header] + rows[:1]) + '\r\n')

# .npy: the dtypes and orders the trial layout meets
def save(name, a, version=None):
    buf = io.BytesIO()
    if version is None:
        np.save(buf, a)
    else:
        np.lib.format.write_array(buf, a, version=version)
    open(f'{C}/npy/{name}.npy', 'wb').write(buf.getvalue())
save('f8_2x3', np.arange(6, dtype='<f8').reshape(2, 3))
save('i4_vector', np.arange(3, dtype='<i4'))
save('bool', np.array([True, False]))
save('fortran', np.asfortranarray(np.arange(6, dtype='<f4').reshape(2, 3)))
save('big_endian', np.arange(4, dtype='>f8'))
save('version2', np.arange(2, dtype='<f8'), version=(2, 0))
save('scalar', np.array(1.5))

# configs: sections, anchors, lists, an enum, near misses
open(f'{C}/config/sections.yaml', 'w').write(
    'tube:\n  length_m: 0.3\n  outer_radius_m: 0.05\nmaterial:\n  youngs_modulus_pa: 3.0e9\n'
    'mics:\n  z_m: [-0.13, -0.13, -0.13, 0.13, 0.13, 0.13]\naudio:\n  sample_rate_hz: 44100\n'
    'ends: free\nnames: [a, b]\n')
open(f'{C}/config/anchors.yaml', 'w').write(
    'audio: &a\n  sample_rate_hz: 48000\nmaterial:\n  density_kg_m3: 1400\nnames: [x]\n')
open(f'{C}/config/flow.yaml', 'w').write('{tube: {length_m: 0.25}, ends: simply-supported}\n')
open(f'{C}/config/bad_type.yaml', 'w').write('tube:\n  length_m: long\n')
open(f'{C}/config/duplicate.yaml', 'w').write('ends: free\nends: free\n')
PY
# a partial dataset: the complete one without its mark
/usr/bin/python3 - "$C" <<'PY'
import shutil, sys, h5py
C = sys.argv[1]
shutil.copy(f'{C}/dataset/two_strikes.h5', f'{C}/dataset/partial.h5')
with h5py.File(f'{C}/dataset/partial.h5', 'r+') as f:
    del f.attrs['complete']
PY
du -sh "$C"/*
