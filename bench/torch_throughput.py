#!/usr/bin/python3
"""Training throughput of the SonicBoom network: our C++ loop against the same model and batch
in PyTorch (Debian's python3-torch), on the same machine, side by side.

Run from the repository root after building (needs build/bin/train_bench):

    /usr/bin/python3 bench/torch_throughput.py [--threads 2] [--steps 8] [--warmup 2]
        [--repeats 3] [--models compact,resnet18,resnet50] [--batch 64] [--out docs/throughput.md]

For each audio encoder it runs the C++ benchmark (`train_bench`, Google Benchmark, which
runs the real training step of learning/train.cc: batch assembly with augmentation, forward,
the paper's loss, backward, Adam) and the PyTorch mirror below with the same shapes, batch,
optimizer and thread count, alternating, `--repeats` times each, and reports the median of
each side: on a shared machine one run of either can be 15 % off. Each C++ run is a fresh
process; the PyTorch runs share this one. The PyTorch model is written to have exactly the C++
network's parameter count, which the script checks before timing. Inputs are random features of the
paper's shapes: mel (6, 50, 517) cropped to 345 frames, GCC (15, 883), proprioception (50, 10).
"""

import argparse
import json
import statistics
import subprocess
import sys
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

CHANNELS, MELS, FRAMES, CROP = 6, 50, 517, 345
PAIRS, LAGS = 15, 883
ROWS, FEATURES = 50, 10


def conv(cin, cout, k, stride, pad):
    return nn.Conv2d(cin, cout, k, stride=stride, padding=pad, bias=False)


class Compact(nn.Module):
    """4 x (conv3x3 [first stride 2] - BN - ReLU - maxpool 2), global average -> 128."""
    features = 128

    def __init__(self, cin):
        super().__init__()
        widths = [16, 32, 64, 128]
        self.convs = nn.ModuleList()
        self.norms = nn.ModuleList()
        for i, w in enumerate(widths):
            self.convs.append(conv(cin, w, 3, 2 if i == 0 else 1, 1))
            self.norms.append(nn.BatchNorm2d(w))
            cin = w

    def forward(self, x):
        for c, n in zip(self.convs, self.norms):
            x = F.relu(n(c(x)))
            x = F.max_pool2d(x, (2 if x.size(2) >= 2 else 1, 2 if x.size(3) >= 2 else 1))
        return x.mean((2, 3))


class Basic(nn.Module):
    expansion = 1

    def __init__(self, cin, planes, stride):
        super().__init__()
        self.c1, self.b1 = conv(cin, planes, 3, stride, 1), nn.BatchNorm2d(planes)
        self.c2, self.b2 = conv(planes, planes, 3, 1, 1), nn.BatchNorm2d(planes)
        self.short = None if stride == 1 and cin == planes else nn.Sequential(
            conv(cin, planes, 1, stride, 0), nn.BatchNorm2d(planes))

    def forward(self, x):
        y = F.relu(self.b1(self.c1(x)))
        y = self.b2(self.c2(y))
        return F.relu(y + (x if self.short is None else self.short(x)))


class Bottleneck(nn.Module):
    expansion = 4

    def __init__(self, cin, planes, stride):
        super().__init__()
        out = planes * 4
        self.c1, self.b1 = conv(cin, planes, 1, 1, 0), nn.BatchNorm2d(planes)
        self.c2, self.b2 = conv(planes, planes, 3, stride, 1), nn.BatchNorm2d(planes)
        self.c3, self.b3 = conv(planes, out, 1, 1, 0), nn.BatchNorm2d(out)
        self.short = None if stride == 1 and cin == out else nn.Sequential(
            conv(cin, out, 1, stride, 0), nn.BatchNorm2d(out))

    def forward(self, x):
        y = F.relu(self.b1(self.c1(x)))
        y = F.relu(self.b2(self.c2(y)))
        y = self.b3(self.c3(y))
        return F.relu(y + (x if self.short is None else self.short(x)))


class ResNet(nn.Module):
    def __init__(self, cin, depth):
        super().__init__()
        block = Bottleneck if depth == 50 else Basic
        counts = [3, 4, 6, 3] if depth == 50 else [2, 2, 2, 2]
        self.stem = nn.Sequential(conv(cin, 64, 7, 2, 3), nn.BatchNorm2d(64), nn.ReLU())
        layers, c = [], 64
        for s, n in enumerate(counts):
            planes = 64 << s
            for b in range(n):
                layers.append(block(c, planes, 2 if (s > 0 and b == 0) else 1))
                c = planes * block.expansion
        self.stages = nn.Sequential(*layers)
        self.features = c

    def forward(self, x):
        x = F.max_pool2d(self.stem(x), 3, 2, 1)
        return self.stages(x).mean((2, 3))


class Block(nn.Module):
    """Pre-norm transformer block with a fused qkv projection and a 4x GELU MLP."""

    def __init__(self, w, heads, p):
        super().__init__()
        self.heads = heads
        self.n1, self.n2 = nn.LayerNorm(w), nn.LayerNorm(w)
        self.qkv, self.out = nn.Linear(w, 3 * w), nn.Linear(w, w)
        self.fc1, self.fc2 = nn.Linear(w, 4 * w), nn.Linear(4 * w, w)
        self.drop = nn.Dropout(p)

    def forward(self, x):
        b, t, w = x.shape
        d = w // self.heads
        qkv = self.qkv(self.n1(x)).reshape(b, t, 3, self.heads, d).permute(2, 0, 3, 1, 4)
        q, k, v = qkv[0], qkv[1], qkv[2]
        a = self.drop(torch.softmax(q @ k.transpose(-2, -1) / d ** 0.5, -1))
        y = (a @ v).transpose(1, 2).reshape(b, t, w)
        x = x + self.drop(self.out(y))
        return x + self.drop(self.fc2(self.drop(F.gelu(self.fc1(self.n2(x))))))


class Network(nn.Module):
    def __init__(self, encoder, w=256, blocks=6, heads=8, p=0.1):
        super().__init__()
        if encoder == "compact":
            self.trunk = Compact(CHANNELS)
            self.proj = nn.Linear(Compact.features, w)
        else:
            self.trunk = ResNet(CHANNELS, 18 if encoder == "resnet18" else 50)
            self.proj = nn.Sequential(nn.Linear(self.trunk.features, 4 * w), nn.LayerNorm(4 * w),
                                      nn.GELU(), nn.Dropout(p), nn.Linear(4 * w, w))
        n = PAIRS * LAGS
        self.gcc = nn.Sequential(nn.LayerNorm(n), nn.Linear(n, 4 * w), nn.LayerNorm(4 * w),
                                 nn.GELU(), nn.Dropout(p), nn.Linear(4 * w, 2 * w),
                                 nn.LayerNorm(2 * w), nn.GELU(), nn.Dropout(p),
                                 nn.Linear(2 * w, w))
        c1 = lambda i, o: nn.Conv1d(i, o, 5, stride=2, padding=2)
        self.prop = nn.Sequential(nn.BatchNorm1d(FEATURES), c1(FEATURES, 16), nn.BatchNorm1d(16),
                                  nn.ReLU(), nn.Dropout(p), c1(16, 32), nn.BatchNorm1d(32),
                                  nn.ReLU(), nn.Dropout(p), c1(32, 128), nn.BatchNorm1d(128),
                                  nn.ReLU())
        self.prop_proj = nn.Linear(128, w)
        self.cls = nn.Parameter(torch.randn(1, 1, w) * 0.02)
        self.emb = nn.Parameter(torch.randn(1, 3, w) * 0.02)
        self.norm = nn.LayerNorm(w)
        self.blocks = nn.ModuleList([Block(w, heads, p) for _ in range(blocks)])
        self.head = nn.Sequential(nn.LayerNorm(w), nn.Linear(w, 2 * w), nn.GELU(), nn.Dropout(p),
                                  nn.Linear(2 * w, 3))
        self.register_buffer("mean", torch.zeros(1, CHANNELS, 1, 1))
        self.register_buffer("std", torch.ones(1, CHANNELS, 1, 1))

    def forward(self, mel, gcc, prop):
        tokens = [self.proj(self.trunk((mel - self.mean) / self.std)),
                  self.gcc(gcc.flatten(1)),
                  self.prop_proj(self.prop(prop.transpose(1, 2)).mean(2))]
        x = torch.stack(tokens, 1) + self.emb
        x = self.norm(torch.cat([self.cls.expand(x.size(0), 1, -1), x], 1))
        for blk in self.blocks:
            x = blk(x)
        return self.head(x[:, 0])


def python_samples_per_s(encoder, batch, steps, warmup, threads):
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    net = Network(encoder)
    params = sum(p.numel() for p in net.parameters())
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    # a random in-memory dataset of 4 batches; each step crops the mel window like the C++ loop
    n = 4 * batch
    mel = torch.rand(n, CHANNELS, MELS, FRAMES)
    gcc = torch.randn(n, PAIRS, LAGS) * 0.01
    prop = torch.randn(n, ROWS, FEATURES)
    target = torch.randn(n, 3)
    weights = torch.tensor([1.0, 5.0, 5.0])
    start0 = (FRAMES - CROP) // 2
    net.train()

    def step(i):
        rows = torch.arange(i * batch, (i + 1) * batch) % n
        shift = int(torch.randint(-34, 35, (1,)))
        m = mel[rows, :, :, start0 + shift:start0 + shift + CROP]
        out = net(m, gcc[rows], prop[rows])
        loss = (((out - target[rows]) ** 2).mean(0) * weights).sum()
        opt.zero_grad()
        loss.backward()
        opt.step()

    for i in range(warmup):
        step(i)
    t0 = time.perf_counter()
    for i in range(steps):
        step(i)
    return params, batch * steps / (time.perf_counter() - t0)


def cpp_samples_per_s(encoder, batch, steps, warmup, threads):
    cmd = ["build/bin/train_bench", "--benchmark_format=json",
           "--benchmark_filter=^TrainStep/%s/%d/%d/" % (encoder, batch, threads),
           "--warmup=%d" % warmup, "--steps=%d" % steps]
    out = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    b = out["benchmarks"][0]
    return int(b["parameters"]), float(b["samples_per_s"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--models", default="compact,resnet18,resnet50")
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    if args.repeats < 1 or args.steps < 1 or args.warmup < 0:
        sys.exit("--repeats and --steps must be >= 1 and --warmup >= 0")
    rows = ["| audio encoder | batch | threads | parameters | C++ samples/s | PyTorch samples/s "
            "| C++ / PyTorch | runs (C++; PyTorch) |", "|---|---|---|---|---|---|---|---|"]
    for enc in args.models.split(","):
        cpp_runs, py_runs = [], []
        for _ in range(args.repeats):
            cpp_params, cpp = cpp_samples_per_s(enc, args.batch, args.steps, args.warmup,
                                                args.threads)
            py_params, py = python_samples_per_s(enc, args.batch, args.steps, args.warmup,
                                                 args.threads)
            if cpp_params != py_params:
                sys.exit("%s: the PyTorch mirror has %d parameters, the C++ network %d: not the "
                         "same model" % (enc, py_params, cpp_params))
            cpp_runs.append(cpp)
            py_runs.append(py)
        cpp, py = statistics.median(cpp_runs), statistics.median(py_runs)
        runs = "%s; %s" % (" ".join("%.1f" % v for v in cpp_runs),
                           " ".join("%.1f" % v for v in py_runs))
        rows.append("| %s | %d | %d | %d | %.1f | %.1f | %.2f | %s |" % (
            enc, args.batch, args.threads, cpp_params, cpp, py, cpp / py, runs))
        print(rows[-1], flush=True)
    text = "\n".join(rows) + "\n"
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
