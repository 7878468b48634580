"""Parity of the grounded probe's pre- and post-processing with Grounded-SAM-2's GroundingDINO code.

No model weights: the functions around the model are called directly with
synthetic inputs -- a BERT WordPiece vocabulary written here (vocab.txt and
the tokenizer.json built from it by transformers' BertTokenizerFast), random
logits (including values on the thresholds) and random boxes, and a stand-in
model object so Grounded-SAM-2's own ``predict`` runs unchanged.  Compared:

1. caption rule and token ids (``preprocess_caption`` + BertTokenizerFast vs
   r360gpu ``caption_for`` + ``DinoTokenizer`` on tokenizer.json and vocab.txt);
2. sub-sentence attention mask and position ids
   (``generate_masks_with_special_tokens_and_transfer_map``);
3. ``predict``: box threshold, text threshold, phrases (``get_phrases_from_posmap``
   + tokenizer.decode), then the demo's pixel scaling and cxcywh -> xyxy; no
   box NMS on either side (Grounded-SAM-2's demos apply none);
4. the image resize (``RandomResize([800], max_size=1333)``: output size and pixels).

Needs torch, transformers, pillow and the fetched Grounded-SAM-2 sources (never committed):

    python bench/parity_grounded.py --gsam2-src /tmp/gsam2-src
"""
from __future__ import annotations

import argparse
import ast
import bisect
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

WORDS = ["a", "the", "red", "blue", "sofa", "chair", "table", "lamp", "on", "of", "potted", "plant", "tv", "monitor",
         "teddy", "bear", "don", "'", "t", "s", "-", "!", ",", "?", ".", "(", ")"]
PIECES = ["##s", "##es", "##ing", "##y", "##le", "##tt"]


def report(name: str, ok: bool, detail: str = "") -> bool:
    print(f"  [{'same' if ok else 'DIFF'}] {name}{(': ' + detail) if detail else ''}")
    return ok


def write_vocab(folder: Path) -> tuple[Path, Path]:
    """vocab.txt laid out like bert-base-uncased's head ([UNK] 100, [CLS] 101, [SEP] 102) and its tokenizer.json."""
    folder.mkdir(parents=True, exist_ok=True)
    vocab = ["[PAD]"] + [f"[unused{i}]" for i in range(99)] + ["[UNK]", "[CLS]", "[SEP]", "[MASK]"] + WORDS + PIECES
    vocab_txt = folder / "vocab.txt"
    vocab_txt.write_text("\n".join(vocab) + "\n", encoding="utf-8")
    tok_json = folder / "tokenizer.json"
    hf_tokenizer(vocab_txt).backend_tokenizer.save(str(tok_json))
    return vocab_txt, tok_json


def hf_tokenizer(vocab_txt: Path):
    """transformers' BERT tokenizer (what GroundingDINO's AutoTokenizer gives) over a vocab.txt:
    the keyword is ``vocab`` from transformers 5 on, ``vocab_file`` before (where an unknown
    keyword silently leaves a default vocabulary)."""
    import inspect

    from transformers import BertTokenizerFast

    key = "vocab" if "vocab" in inspect.signature(BertTokenizerFast.__init__).parameters else "vocab_file"
    tok = BertTokenizerFast(**{key: str(vocab_txt)}, do_lower_case=True, clean_up_tokenization_spaces=True)
    ids = tok("[CLS]", add_special_tokens=False)["input_ids"]
    if ids != [101]:
        raise SystemExit(f"transformers did not read {vocab_txt} ([CLS] -> {ids})")
    return tok


def load_functions(path: Path, names: list[str], namespace: dict) -> dict:
    """The named top-level functions of a fetched source file, executed in ``namespace``
    (so the module's heavy imports -- the model, torchvision.models -- are not needed)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    body = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name in names]
    missing = set(names) - {n.name for n in body}
    if missing:
        raise SystemExit(f"{path}: no function(s) {sorted(missing)}")
    exec(compile(ast.Module(body=body, type_ignores=[]), str(path), "exec"), namespace)  # noqa: S102
    return namespace


class FakeDino:
    """What ``predict`` needs of the model: ``tokenizer`` and a call returning logits and boxes."""

    def __init__(self, tokenizer, logits, boxes):
        self.tokenizer, self._logits, self._boxes = tokenizer, logits, boxes

    def to(self, device):
        return self

    def __call__(self, image, captions):
        import torch

        return {"pred_logits": torch.from_numpy(self._logits)[None], "pred_boxes": torch.from_numpy(self._boxes)[None]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gsam2-src", required=True, help="folder holding the fetched Grounded-SAM-2 repository")
    ap.add_argument("--work", default="/tmp/probes-parity-grounded")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    import torch

    from r360gpu.probes import grounded as G
    from r360gpu.probes.preprocess import as_rgb01, dino_encoder_input, dino_input_shape

    src = Path(args.gsam2_src).resolve()
    gd = src / "grounding_dino" / "groundingdino"
    ns = load_functions(gd / "util" / "utils.py", ["get_phrases_from_posmap"], {"torch": torch, "Dict": dict,
                                                                                 "AutoTokenizer": object})
    ns = load_functions(gd / "util" / "inference.py", ["preprocess_caption", "predict"],
                        {**ns, "torch": torch, "bisect": bisect, "Tuple": tuple, "List": list})
    ns = load_functions(gd / "models" / "GroundingDINO" / "bertwarper.py",
                        ["generate_masks_with_special_tokens_and_transfer_map"], {**ns, "torch": torch})
    ns = load_functions(gd / "util" / "box_ops.py", ["box_cxcywh_to_xyxy"], {**ns, "torch": torch})
    try:
        import torchvision.transforms.functional as tv_f
    except Exception:  # noqa: BLE001 - a CUDA torchvision wheel beside a CPU torch
        for name in [m for m in sys.modules if m.split(".")[0] == "torchvision"]:
            del sys.modules[name]
        sys.path.insert(0, str(HERE / "torchvision_standin"))
        import torchvision.transforms.functional as tv_f
    transforms_ns = load_functions(gd / "datasets" / "transforms.py", ["resize"], {"torch": torch, "F": tv_f})
    rng = np.random.default_rng(args.seed)
    vocab_txt, tok_json = write_vocab(Path(args.work))
    hf = hf_tokenizer(vocab_txt)
    tokenizers = {"tokenizer.json": G.DinoTokenizer(tok_json)}
    try:
        tokenizers["vocab.txt"] = G.DinoTokenizer(vocab_txt)
    except Exception as exc:  # noqa: BLE001 - reported, not fatal: the comparison runs on what loads
        print(f"  (r360gpu cannot read vocab.txt: {str(exc).splitlines()[0]})")
    results = []
    print(f"torch {torch.__version__}; Grounded-SAM-2 from {src}; seed {args.seed}")

    print("1. caption rule and token ids")
    prompts = ["sofa", "Red Sofa", "  chair ", "chair.", "sofas . chair", "the chair?", "potted plant",
               "teddy bear .", "tv-monitor", "don't", "Lamp!", "table (red)", "unknownword"]
    for name, tok in tokenizers.items():
        bad = []
        for p in prompts:
            ids_off = hf(ns["preprocess_caption"](p))["input_ids"]
            ids_r = tok.encode(G.caption_for(p)).tolist()
            if ids_off != ids_r:
                bad.append((p, ids_off, ids_r))
        results.append(report(f"token ids of {len(prompts)} prompts via {name}", not bad,
                              f"{len(bad)} differ, e.g. {bad[0]}" if bad else ""))

    print("2. sub-sentence attention mask and position ids")
    special = hf.convert_tokens_to_ids(G.SPECIAL_TOKENS)
    bad = 0
    for p in prompts:
        ids = hf(ns["preprocess_caption"](p), return_tensors="pt")
        att, pos, _ = ns["generate_masks_with_special_tokens_and_transfer_map"](ids, special, hf)
        m_r, p_r = G.sub_sentence_masks(ids["input_ids"][0].numpy(), tokenizers["tokenizer.json"].special_ids)
        bad += not (np.array_equal(att[0].numpy(), m_r) and np.array_equal(pos[0].numpy(), p_r))
    results.append(report(f"masks and positions of {len(prompts)} captions", bad == 0, f"{bad} differ" if bad else ""))

    print("3. predict(): thresholds, phrases, boxes")
    bad_keep = bad_phrase = 0
    score_ulp = 0.0
    box_err = 0.0
    n_det = 0
    for trial in range(60):
        p = prompts[trial % len(prompts)]
        caption = ns["preprocess_caption"](p)
        n_tok = len(hf(caption)["input_ids"])
        q = 300
        logits = rng.normal(-3, 2.5, (q, 256)).astype(np.float32)
        logits[:, n_tok:] = -np.inf  # the model masks positions past the caption
        box_t = float(rng.choice([0.2, 0.35, 0.5]))
        text_t = float(rng.choice([0.1, 0.25, 0.4]))
        # Values exactly on the thresholds (sigmoid(logit(t)) in float32) test the '>' comparisons.
        for t in (box_t, text_t):
            logits[rng.integers(0, q, 20), rng.integers(0, n_tok, 20)] = np.float32(np.log(t / (1 - t)))
        boxes = rng.uniform(0.05, 0.95, (q, 4)).astype(np.float32)
        boxes[1] = boxes[0]  # duplicates: neither side suppresses them
        logits[1] = logits[0]
        h, w = int(rng.integers(50, 1500)), int(rng.integers(50, 1500))
        model = FakeDino(hf, logits, boxes)
        b_off, s_off, ph_off = ns["predict"](model, torch.zeros(3, 8, 8), p, box_t, text_t, device="cpu")
        xyxy_off = ns["box_cxcywh_to_xyxy"](b_off * torch.Tensor([w, h, w, h])).numpy()
        for name, tok in tokenizers.items():
            ids = tok.encode(G.caption_for(p))
            det = G.select_detections(logits, boxes, ids, tok.id_to_token, (h, w), box_t, text_t)
            if det.count != len(ph_off):
                bad_keep += 1
                continue
            n_det += det.count
            bad_phrase += sum(a != b for a, b in zip(ph_off, det.phrases))
            if det.count:
                score_ulp = max(score_ulp, float(np.abs(s_off.numpy() - det.scores).max() / np.spacing(np.float32(0.5))))
            if det.count:
                box_err = max(box_err, float(np.abs(xyxy_off - det.boxes).max()))
    results.append(report("kept detections (box threshold, '>' on float32 sigmoid)", bad_keep == 0,
                          f"{bad_keep} of {60 * len(tokenizers)} runs keep a different number" if bad_keep else ""))
    results.append(report(f"phrases of {n_det} detections (text threshold, WordPiece decoding)", bad_phrase == 0,
                          f"{bad_phrase} differ" if bad_phrase else ""))
    results.append(report("scores (float32 sigmoid; torch's vectorised one is within 1 ulp of correct rounding)",
                          score_ulp <= 2.0, f"max |diff| {score_ulp:.1f} ulp at 0.5"))
    results.append(report("pixel xyxy boxes", box_err == 0.0, f"max |diff| {box_err:.3g} px"))

    print("4. image resize (RandomResize([800], max_size=1333))")
    from PIL import Image

    bad = []
    for _ in range(300):
        h, w = int(rng.integers(1, 3000)), int(rng.integers(1, 3000))
        img = Image.new("RGB", (w, h))
        out, _ = transforms_ns["resize"](img, None, 800, 1333)
        if (out.size[1], out.size[0]) != dino_input_shape(h, w, 800, 1333):
            bad.append((h, w))
    results.append(report("output size of 300 random image sizes", not bad, f"{len(bad)} differ: {bad[:3]}" if bad else ""))
    worst = 0.0
    for h, w in ((480, 640), (1080, 1920), (300, 200), (900, 1200), (1, 700), (2000, 3)):
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        pil, _ = transforms_ns["resize"](Image.fromarray(img), None, 800, 1333)
        ref = torch.from_numpy(np.asarray(pil).copy()).permute(2, 0, 1).float().div(255)  # ToTensor
        # torchvision's F.normalize on a float32 tensor (sub_, div_ by float32 mean / std)
        mean = torch.as_tensor([0.485, 0.456, 0.406], dtype=torch.float32)[:, None, None]
        std = torch.as_tensor([0.229, 0.224, 0.225], dtype=torch.float32)[:, None, None]
        ref = ref.sub_(mean).div_(std).numpy()[None]
        r = dino_encoder_input(as_rgb01(img), dino_input_shape(h, w))
        worst = max(worst, float(np.abs(ref - r).max() * 0.229 * 255))
    results.append(report("normalised image tensor (PIL resize, ToTensor, Normalize)", worst == 0.0,
                          f"max |diff| {worst:.3g} grey levels"))
    print(f"summary: {sum(results)} of {len(results)} checks agree")
    return 0 if all(results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
