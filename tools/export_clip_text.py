#!/usr/bin/env python3
"""Exports CLIP's text tower to ONNX for `omcl encode text` and the map
grounding / prompt steps, with the model card omcl reads beside it.

Needs torch and open_clip (`pip install torch open_clip_torch onnx onnxruntime`)
and the CLIP weights (open_clip fetches them on first use, or pass
--checkpoint). Not run in CI: no weights there. The contract it produces is the
one tests/encode_models.rs checks on a tiny stand-in model:

    input  input_ids     int64 [N, 77]   CLIP token ids, <|startoftext|> ... <|endoftext|> 0 0 ...
    output text_features float32 [N, F]  (omcl normalises to unit length)

Usage:
    python tools/export_clip_text.py --arch ViT-B-32 --pretrained openai --out models/clip_vitb32_text.onnx
LSeg's text encoder is CLIP ViT-B/32 (`--arch ViT-B-32`); OpenScene's 2-D
fusion features use ViT-L/14@336 (`--arch ViT-L-14-336`).
"""
import argparse
import json
import os

import numpy as np
import torch


class TextTower(torch.nn.Module):
    """CLIP's text encoder with the projection: token ids to text features."""

    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, input_ids):
        return self.model.encode_text(input_ids)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arch", default="ViT-B-32", help="open_clip architecture name")
    ap.add_argument("--pretrained", default="openai", help="open_clip pretrained tag")
    ap.add_argument("--checkpoint", help="local weights file instead of --pretrained")
    ap.add_argument("--out", required=True, help="output .onnx; the card goes beside it")
    ap.add_argument("--opset", type=int, default=17)
    args = ap.parse_args()

    import open_clip

    pretrained = args.checkpoint or args.pretrained
    model, _, _ = open_clip.create_model_and_transforms(args.arch, pretrained=pretrained)
    model.eval()
    tokenizer = open_clip.get_tokenizer(args.arch)
    tower = TextTower(model).eval()

    prompts = ["a photo of a chair", "toilet", "floor"]
    tokens = tokenizer(prompts).to(torch.int64)
    with torch.no_grad():
        reference = tower(tokens).numpy()

    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    torch.onnx.export(
        tower,
        (tokens,),
        args.out,
        input_names=["input_ids"],
        output_names=["text_features"],
        dynamic_axes={"input_ids": {0: "n"}, "text_features": {0: "n"}},
        opset_version=args.opset,
        do_constant_folding=True,
    )
    card = {
        "kind": "text",
        "name": f"clip_{args.arch.lower().replace('-', '')}",
        "feature_dim": int(reference.shape[1]),
        "normalize": True,
        "text": {"input": "input_ids", "output": "text_features", "context_length": int(tokens.shape[1])},
    }
    card_path = os.path.splitext(args.out)[0] + ".card.json"
    with open(card_path, "w") as f:
        json.dump(card, f, indent=2)
        f.write("\n")

    # Check the export against torch, and print token ids to compare with
    # `omcl encode tokens`.
    try:
        import onnxruntime as ort

        got = ort.InferenceSession(args.out).run(None, {"input_ids": tokens.numpy()})[0]
        print("max |onnx - torch| =", float(np.abs(got - reference).max()))
    except ImportError:
        print("onnxruntime not installed: export not checked")
    for p, t in zip(prompts, tokens.numpy()):
        print(repr(p), [int(x) for x in t if x != 0])
    print("wrote", args.out, "and", card_path)


if __name__ == "__main__":
    main()
