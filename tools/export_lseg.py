#!/usr/bin/env python3
"""Exports LSeg's image encoder (per-pixel CLIP-space features) to ONNX for
`omcl encode image` and the RGB-D mapping / localisation feature sources, with
the model card omcl reads beside it.

Needs: torch, onnx, onnxruntime (to check), a clone of the LSeg repository
(isl-org/lang-seg, for `modules/models/lseg_net.py`) and its checkpoint
(`demo_e200.ckpt`, ViT-L/16 at 384 px, as VLMaps and OMCL use). Not run in
CI: no weights there. The contract it produces is the one
tests/encode_models.rs checks on tiny stand-in models:

    input  image     float32 [1, 3, 480, 480]  RGB, (x / 255 - 0.5) / 0.5
    output features  float32 [1, 512, 480, 480] per-pixel features

The features are what VLMaps' `LSegEncNet` returns: the head's 512-d output,
unit-normalised per pixel, upsampled 2x bilinearly to the input size. The
card tells omcl to resize the longer image side to 520 px and slide 480 px
windows with a 320 px stride (VLMaps' base_size, crop_size and 2/3 stride),
averaging overlaps.

Usage:
    python tools/export_lseg.py --repo ~/lang-seg --checkpoint ~/lang-seg/checkpoints/demo_e200.ckpt \\
        --out models/lseg_vitl16_480.onnx
"""
import argparse
import json
import os
import sys

import numpy as np
import torch
import torch.nn.functional as F


class LSegPixelEncoder(torch.nn.Module):
    """LSegNet's image path only: ViT backbone, refinement, head, normalise, upsample."""

    def __init__(self, net, forward_vit):
        super().__init__()
        self.net = net
        self.forward_vit = forward_vit

    def forward(self, image):
        net = self.net
        layer_1, layer_2, layer_3, layer_4 = self.forward_vit(net.pretrained, image)
        l1 = net.scratch.layer1_rn(layer_1)
        l2 = net.scratch.layer2_rn(layer_2)
        l3 = net.scratch.layer3_rn(layer_3)
        l4 = net.scratch.layer4_rn(layer_4)
        p4 = net.scratch.refinenet4(l4)
        p3 = net.scratch.refinenet3(p4, l3)
        p2 = net.scratch.refinenet2(p3, l2)
        p1 = net.scratch.refinenet1(p2, l1)
        feats = net.scratch.head1(p1)  # [1, 512, H/2, W/2]
        feats = feats / feats.norm(dim=1, keepdim=True)
        return F.interpolate(feats, scale_factor=2, mode="bilinear", align_corners=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repo", required=True, help="clone of isl-org/lang-seg")
    ap.add_argument("--checkpoint", required=True, help="LSeg checkpoint, e.g. demo_e200.ckpt")
    ap.add_argument("--out", required=True, help="output .onnx; the card goes beside it")
    ap.add_argument("--size", type=int, default=480, help="window side in pixels (multiple of 32)")
    ap.add_argument("--base-size", type=int, default=520, help="longer image side after resizing")
    ap.add_argument("--opset", type=int, default=17)
    args = ap.parse_args()

    sys.path.insert(0, os.path.abspath(args.repo))
    from modules.models.lseg_net import LSegNet  # noqa: E402  (from the LSeg repo)
    from modules.models.lseg_vit import forward_vit  # noqa: E402

    net = LSegNet(
        labels=["other"],
        backbone="clip_vitl16_384",
        features=256,
        crop_size=args.size,
        arch_option=0,
        block_depth=0,
        activation="lrelu",
    )
    state = torch.load(args.checkpoint, map_location="cpu")
    state = state.get("state_dict", state)
    # Lightning checkpoints prefix the network's keys with "net.".
    state = {k[len("net."):] if k.startswith("net.") else k: v for k, v in state.items()}
    missing, unexpected = net.load_state_dict(state, strict=False)
    print(f"weights loaded: {len(missing)} missing, {len(unexpected)} unexpected keys")
    enc = LSegPixelEncoder(net, forward_vit).eval()

    x = torch.rand(1, 3, args.size, args.size) * 2 - 1
    with torch.no_grad():
        reference = enc(x).numpy()
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    torch.onnx.export(
        enc, (x,), args.out, input_names=["image"], output_names=["features"], opset_version=args.opset
    )
    stride = args.size * 2 // 3
    card = {
        "kind": "image",
        "name": "lseg_vitl16_384",
        "feature_dim": int(reference.shape[1]),
        "normalize": True,
        "image": {
            "input": "image",
            "output": "features",
            "layout": "nchw",
            "output_layout": "nchw",
            "resize": {"mode": "longer_side", "size": args.base_size},
            "filter": "bilinear",
            "mean": [0.5, 0.5, 0.5],
            "std": [0.5, 0.5, 0.5],
            "window": {"width": args.size, "height": args.size, "stride_x": stride, "stride_y": stride},
        },
    }
    card_path = os.path.splitext(args.out)[0] + ".card.json"
    with open(card_path, "w") as f:
        json.dump(card, f, indent=2)
        f.write("\n")
    try:
        import onnxruntime as ort

        got = ort.InferenceSession(args.out).run(None, {"image": x.numpy()})[0]
        print("max |onnx - torch| =", float(np.abs(got - reference).max()))
    except ImportError:
        print("onnxruntime not installed: export not checked")
    print("wrote", args.out, "and", card_path)


if __name__ == "__main__":
    main()
