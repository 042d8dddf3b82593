#!/usr/bin/python3
"""FFDNet and GAP-FFDNet in PyTorch-CPU: the reference the C implementation (recon/cnn/ffdnet.c,
recon/pnp_ffdnet.c) is checked and timed against. Needs Debian's python3-torch (not a dependency of the project:
the tests compare against the fixtures this script wrote, bench_pnp_ffdnet calls it when torch is there).

  bench/ffdnet_torch.py fixtures OUTDIR      reference outputs for tests/unit/test_cnn_ffdnet.c
  bench/ffdnet_torch.py bench --dir DIR      the PyTorch side of bench/bench_pnp_ffdnet.c (one JSON line)

The network (IPOL FFDNet, whose weights PnP-SCI ships): a noise map of C channels filled with sigma, then the
2x2 pixel-unshuffle of the image (channel 4c + k holds colour c at row offset k // 2, column offset k % 2),
3x3 convolutions without bias (batch norm + ReLU between), the output shuffled back is the noise:
denoised = x - net(x, sigma), not clamped. Odd sizes: the last row / column repeated, then cropped.
"""
import argparse
import json
import os
import resource
import sys
import time

import numpy as np
import torch
import torch.nn as nn


def build(path):
    """An nn.Sequential with the state dict of `path` (keys module.intermediate_dncnn.itermediate_dncnn.<i>.*)."""
    sd = torch.load(path, map_location="cpu")
    sd = {k.split("itermediate_dncnn.")[1]: v for k, v in sd.items()}
    c_in, feat = sd["0.weight"].shape[1], sd["0.weight"].shape[0]
    layers = [nn.Conv2d(c_in, feat, 3, padding=1, bias=False), nn.ReLU()]
    i = 2
    while f"{i + 1}.running_mean" in sd:
        layers += [nn.Conv2d(feat, feat, 3, padding=1, bias=False), nn.BatchNorm2d(feat), nn.ReLU()]
        i += 3
    layers.append(nn.Conv2d(feat, sd[f"{i}.weight"].shape[0], 3, padding=1, bias=False))
    net = nn.Sequential(*layers)
    net.load_state_dict(sd)
    net.eval()
    return net, c_in // 5


def denoise(net, c, x, sigma):
    """x: (B, C, H, W) float32 tensor on [0, 1]; sigma on [0, 1]. Returns x - noise estimate."""
    b, _, h, w = x.shape
    xp = x
    if h % 2:
        xp = torch.cat([xp, xp[:, :, -1:, :]], 2)
    if w % 2:
        xp = torch.cat([xp, xp[:, :, :, -1:]], 3)
    h2, w2 = xp.shape[2] // 2, xp.shape[3] // 2
    down = torch.empty(b, 4 * c, h2, w2)
    for k, (dy, dx) in enumerate([(0, 0), (0, 1), (1, 0), (1, 1)]):
        down[:, k::4] = xp[:, :, dy::2, dx::2]
    noise_map = torch.full((b, c, h2, w2), float(sigma))
    with torch.no_grad():
        out = net(torch.cat([noise_map, down], 1))
    up = torch.empty_like(xp)
    for k, (dy, dx) in enumerate([(0, 0), (0, 1), (1, 0), (1, 1)]):
        up[:, :, dy::2, dx::2] = out[:, k::4]
    return x - up[:, :, :h, :w]


def test_image(c, h, w, sigma, rng):
    """Smooth shapes, edges and texture on [0, 1], plus Gaussian noise of sigma."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.empty((c, h, w))
    for ch in range(c):
        base = 0.45 + 0.25 * np.sin(xx / (9.0 + 3 * ch)) * np.cos(yy / (13.0 - 2 * ch))
        disc = ((xx - w * 0.35) ** 2 + (yy - h * 0.4) ** 2) < (min(h, w) * 0.2) ** 2
        rect = (xx > w * 0.55) & (xx < w * 0.85) & (yy > h * 0.5) & (yy < h * 0.8)
        stripes = 0.15 * ((xx.astype(int) // 4 + ch) % 2)
        img[ch] = base + 0.3 * disc - 0.25 * rect + stripes * (yy < h * 0.25)
    img = np.clip(img, 0, 1) + rng.normal(0, sigma, img.shape)
    return img.astype(np.float32)


def fixtures(outdir):
    os.makedirs(outdir, exist_ok=True)
    data = os.environ.get("SCICAP_DATA", os.path.join(os.path.dirname(__file__), "../../shared/data"))
    cases = []
    rng = np.random.default_rng(2020)
    for net_name, c in (("net_gray.pth", 1), ("net_rgb.pth", 3)):
        net, cc = build(os.path.join(data, "ffdnet", net_name))
        assert cc == c
        for h, w in ((256, 256), (61, 83)):
            # one noisy input per size, at the middle noise level; every sigma denoises that same input
            x = test_image(c, h, w, 25 / 255, rng)
            tag = f"{'gray' if c == 1 else 'rgb'}_{w}x{h}"
            x.tofile(os.path.join(outdir, f"in_{tag}.f32"))
            for s in (6, 25, 50):
                y = denoise(net, c, torch.from_numpy(x)[None], s / 255)[0].numpy().astype(np.float32)
                y.tofile(os.path.join(outdir, f"out_{tag}_s{s}.f32"))
                cases.append({"net": "gray" if c == 1 else "rgb", "weights": net_name, "c": c, "h": h, "w": w,
                              "sigma": s / 255, "input": f"in_{tag}.f32", "output": f"out_{tag}_s{s}.f32"})
                print(f"{tag} sigma {s}: max |out - in| {np.abs(y - x).max():.4f}")
    with open(os.path.join(outdir, "manifest.json"), "w") as f:
        json.dump({"made_by": "bench/ffdnet_torch.py fixtures", "torch": torch.__version__,
                   "layout": "C x H x W float32, little-endian, rows contiguous", "cases": cases}, f, indent=1)


def bench(d, threads, repeat):
    torch.set_num_threads(threads)
    meta = json.load(open(os.path.join(d, "meta.json")))
    w, h, n = meta["w"], meta["h"], meta["n"]
    mask = np.fromfile(os.path.join(d, "mask.f32"), np.float32).reshape(n, h, w)
    meas = np.fromfile(os.path.join(d, "meas.f32"), np.float32).reshape(h, w)
    tp = os.path.join(d, "truth.f32")
    truth = np.fromfile(tp, np.float32).reshape(n, h, w) if os.path.exists(tp) else None
    net, c = build(meta["weights"])
    frame = torch.from_numpy((truth if truth is not None else mask)[:1].copy())[None]
    batch = torch.from_numpy((truth if truth is not None else mask).copy())[:, None]
    denoise(net, c, frame, 25 / 255)
    t1 = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        denoise(net, c, frame, 25 / 255)
        t1.append(time.perf_counter() - t0)
    t8 = []
    for _ in range(max(1, repeat // 2)):
        t0 = time.perf_counter()
        denoise(net, c, batch, 25 / 255)
        t8.append((time.perf_counter() - t0) / n)
    # GAP-FFDNet: accelerated GAP, the n frames denoised as one batch per iteration
    t0 = time.perf_counter()
    phi = (mask ** 2).sum(0)
    phi[phi == 0] = 1  # pixels no mask opens: no data update, as the C code's guard
    x = mask * meas
    ybar = np.zeros_like(meas)
    for sigma, iters in zip(meta["sigma"], meta["iters"]):
        for _ in range(iters):
            yhat = (mask * x).sum(0)
            if meta["accelerate"]:
                ybar += meas - yhat
                r = (ybar - yhat) / phi
            else:
                r = (meas - yhat) / phi
            x = x + meta["lambda"] * mask * r
            x = denoise(net, c, torch.from_numpy(x.astype(np.float32))[:, None], sigma / 255)[:, 0].numpy()
    solve = time.perf_counter() - t0
    out = {"torch": torch.__version__, "threads": threads, "mkldnn": torch.backends.mkldnn.is_available(),
           "denoise_frame_s": float(np.median(t1)), "denoise_batch_frame_s": float(np.median(t8)),
           "solve_s": solve, "solve_batched": True,
           "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    if truth is not None:
        mse = ((x - truth) ** 2).reshape(n, -1).mean(1)
        out["psnr"] = float(np.mean(10 * np.log10(truth.reshape(n, -1).max(1) ** 2 / mse)))
        out["psnr_peak1"] = float(np.mean(10 * np.log10(1 / mse)))
    print(json.dumps(out))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("fixtures")
    f.add_argument("outdir")
    b = sub.add_parser("bench")
    b.add_argument("--dir", required=True)
    b.add_argument("--threads", type=int, default=2)
    b.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args()
    if a.cmd == "fixtures":
        fixtures(a.outdir)
    else:
        bench(a.dir, a.threads, a.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
