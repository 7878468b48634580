"""Compute a prompt decoder's prompt-independent tensors once per run instead of once per prompt.

A SAM decoder exported with a dynamic prompt axis repeats the image embedding
(and its positional encoding, and the dense "no mask" embedding) along that
axis before work that does not depend on the prompt: in segment-anything's
first two-way-attention layer, the token->image attention's key and value
projections of the image and the image->token attention's query projection
are the same for every prompt.  onnxruntime computes them once per prompt.

:func:`hoist_prompt_invariant` rewrites such a graph.  Every tensor is put in
one of three classes, from the inputs that carry one row per prompt
(``per_prompt``):

* *varying*: its values depend on the prompts' values (a data path from a
  per-prompt input; every operator counts as data except ``Shape`` / ``Size``,
  whose outputs carry only the inputs' shapes);
* *batch-shaped*: it depends on the per-prompt inputs only through their
  shapes, i.e. on the number of prompts B and on nothing the prompts say
  (the repeated image embedding, everything computed from it before it meets a
  prompt, and the shape arithmetic around them);
* *invariant*: the rest.

An edge where a batch-shaped tensor T enters a broadcasting operator
(``Add``, ``Sub``, ``Mul``, ``Div``, ``MatMul``) beside a varying input of
the same rank is re-pointed at T's *batch-1 twin*: T as the graph computes it
when every per-prompt input is cut to its first row (a clone of T's producers
fed ``input[:1]``).  When T is B copies of one row along the leading axis,
which is what repeating the image embedding makes, the operator broadcasts the
twin to the same operands it read before, so every element of its output is
the same arithmetic on the same numbers (a MatMul's right operand only when it
keeps a batch axis besides the prompt axis, such as attention heads: with the
prompt axis alone onnxruntime may multiply every prompt's rows as one matrix,
a product with other roundings); the nodes that only fed the
re-pointed edges are then dropped (their work ran once per prompt, the twin's
runs once per batch).

Why exact, and what is checked: broadcasting hands each output element the
same operand values as the repeated tensor did, and the element is then the
same arithmetic provided the kernel computes it the same way for a broadcast
operand as for a repeated one: onnxruntime's CPU kernels do for elementwise
operators and for MatMul whose broadcast operand keeps another batch axis
(tests/test_onnx_hoist.py compares bit patterns at 1, 2, 7 and 64 prompts;
bench/bench_decoder.py on the real SAM and SAM 2.1 exports).  What the graph
alone cannot show is that a batch-shaped tensor really is B copies of its
first row (a ``Range`` over B is batch-shaped and is not).  The caller
therefore runs the original and the rewritten graph on the same inputs at two
batch sizes before using the rewrite (:func:`outputs_identical`, called by
``SamModels`` when it opens a batched decoder) and keeps the original graph
unless every output it reads is bit-identical.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

__all__ = ["hoist_prompt_invariant", "outputs_identical"]

#: Operators that only read their input's shape.
_SHAPE_ONLY = frozenset({"Shape", "Size"})
#: Operators with numpy-style broadcasting over every operand axis (MatMul over its batch axes).
_BROADCASTING = frozenset({"Add", "Sub", "Mul", "Div", "MatMul"})
_TWIN_SUFFIX = "__batch1"


def hoist_prompt_invariant(
    model, per_prompt: Iterable[str], same_rows: Iterable[str] = (), shapes_from_twins: bool = True
):
    """A copy of ``model`` (an ``onnx.ModelProto``) whose batch-shaped operands of broadcasting
    operators are computed for one prompt and broadcast (see the module docstring), or None when
    there is nothing to re-point or the graph has subgraphs (If / Loop / Scan: not analysed).

    per_prompt: names of the graph inputs that hold one row per prompt along axis 0 (in the
    graph's input order, the first gives the number of prompts B).  same_rows: inputs with one
    row per prompt that the caller always feeds with identical rows (a SAM 2 decoder's
    ``mask_input`` of zeros): batch-shaped, like a repeat inside the graph.  shapes_from_twins: a
    ``Shape`` of a batch-shaped tensor becomes B followed by its twin's shape past axis 0, so
    that the repeated tensor is not computed for its shape alone; right when the tensor's prompt
    axis is axis 0 (the check the caller runs tells; without it, the repeat stays for the
    ``Shape`` nodes that read it).
    """
    import onnx

    graph = model.graph
    if any(a.HasField("g") or len(a.graphs) for n in graph.node for a in n.attribute):
        return None
    per_prompt, same_rows = set(per_prompt), set(same_rows) - set(per_prompt)
    inputs = [i.name for i in graph.input if i.name in per_prompt]
    if not inputs:
        return None
    varying, batch_shaped = _classify(graph.node, per_prompt, same_rows)
    types = _types(model)
    ranks = {name: rank for name, (_, rank) in types.items()}

    rewired: list[tuple[int, int]] = []  # (node index, input index) read from the twin
    for k, node in enumerate(graph.node):
        if node.op_type not in _BROADCASTING or not any(i in varying for i in node.input):
            continue
        operand_ranks = {ranks.get(i) for i in node.input}
        if len(node.input) != 2 or len(operand_ranks) != 1 or None in operand_ranks:
            continue  # equal known ranks: the twin's leading 1 lines up with the prompt axis
        for j, name in enumerate(node.input):
            if name not in batch_shaped:
                continue
            if node.op_type == "MatMul" and (ranks[name] < 3 or (j == 1 and ranks[name] < 4)):
                # 2-D: the leading axis is a matrix axis.  A right operand whose only batch axis
                # is the prompt axis would become one matrix for every prompt, which onnxruntime
                # may multiply with every prompt's rows at once, rounding otherwise.
                continue
            rewired.append((k, j))
    if not rewired:
        return None

    out = onnx.ModelProto()
    out.CopyFrom(model)
    g = out.graph
    twins: dict[str, str] = {}
    clones: list = []
    producer = {o: n for n in model.graph.node for o in n.output}  # the nodes as they were

    def twin(name: str) -> str:
        """The batch-1 twin of ``name``, cloning its producers as needed (depth-first, no recursion)."""
        stack = [name]
        while stack:
            top = stack[-1]
            if top in twins:
                stack.pop()
            elif top in per_prompt or top in same_rows:
                twins[top] = top + _TWIN_SUFFIX
                clones.append(_first_row_node(onnx, top, twins[top], g))
            elif top not in varying and top not in batch_shaped:
                twins[top] = top  # invariant: the same tensor for any number of prompts
            else:
                node = producer[top]
                missing = [i for i in node.input if i and i not in twins]
                if missing:
                    stack.extend(missing)
                    continue
                clone = onnx.NodeProto()
                clone.CopyFrom(node)
                clone.name = (node.name or node.output[0]) + _TWIN_SUFFIX
                del clone.input[:]
                clone.input.extend(twins[i] if i else "" for i in node.input)
                del clone.output[:]
                clone.output.extend(o + _TWIN_SUFFIX if o else "" for o in node.output)
                twins.update({o: o + _TWIN_SUFFIX for o in node.output if o})
                clones.append(clone)
        return twins[name]

    for k, j in rewired:
        g.node[k].input[j] = twin(g.node[k].input[j])
    opset = max((o.version for o in out.opset_import if o.domain in ("", "ai.onnx")), default=0)
    if shapes_from_twins and opset >= 15:  # Shape's start / end attributes
        count = _prompt_count(onnx, g, inputs[0])
        for k, node in enumerate(list(g.node)):
            data = node.input[0] if node.op_type == "Shape" and not node.attribute else None
            if data in batch_shaped and _is_float(types, data):
                twin_shape = node.output[0] + "__tail" + _TWIN_SUFFIX
                clones.append(onnx.helper.make_node("Shape", [twin(data)], [twin_shape], name=twin_shape, start=1))
                g.node[k].CopyFrom(
                    onnx.helper.make_node("Concat", [count, twin_shape], list(node.output), name=node.name, axis=0)
                )
    g.node.extend(clones)
    _toposort(g)
    _prune_to_outputs(g)
    return out


def _classify(nodes, per_prompt: set[str], same_rows: set[str] = frozenset()) -> tuple[set[str], set[str]]:
    """(varying, batch-shaped) tensor names; nodes in topological order, as ONNX requires."""
    varying = set(per_prompt)
    batch_shaped = set(same_rows)
    for node in nodes:
        ins = [i for i in node.input if i]
        if node.op_type in _SHAPE_ONLY:
            hit = any(i in varying or i in batch_shaped for i in ins)
            target = batch_shaped
        elif any(i in varying for i in ins):
            hit, target = True, varying
        else:
            hit, target = any(i in batch_shaped for i in ins), batch_shaped
        if hit:
            target.update(o for o in node.output if o)
    return varying, batch_shaped


def _types(model) -> dict[str, tuple[int, int]]:
    """Tensor name -> (element type, rank), where onnx's shape inference knows them."""
    import onnx

    try:
        inferred = onnx.shape_inference.infer_shapes(model)
    except Exception:  # noqa: BLE001 - no ranks: nothing is re-pointed
        return {}
    g = inferred.graph
    out = {}
    for v in list(g.input) + list(g.value_info) + list(g.output):
        t = v.type.tensor_type
        if t.HasField("shape"):
            out[v.name] = (t.elem_type, len(t.shape.dim))
    for t in g.initializer:
        out[t.name] = (t.data_type, len(t.dims))
    return out


def _is_float(types, name: str) -> bool:
    """Whether ``name`` is known to be a floating-point tensor (data, not a shape vector)."""
    import onnx

    floats = {onnx.TensorProto.FLOAT, onnx.TensorProto.FLOAT16, onnx.TensorProto.DOUBLE, onnx.TensorProto.BFLOAT16}
    return types.get(name, (None, 0))[0] in floats and types[name][1] >= 1


def _prompt_count(onnx, graph, name: str) -> str:
    """Adds ``B = Shape(name)[0:1]`` to ``graph``; returns its name."""
    out = name + "__prompts" + _TWIN_SUFFIX
    graph.node.append(onnx.helper.make_node("Shape", [name], [out], name=out, start=0, end=1))
    return out


def _first_row_node(onnx, name: str, out_name: str, graph):
    """``out_name = name[0:1]`` (a Slice on axis 0 whose bounds are new initializers)."""
    bounds = []
    for suffix, value in (("starts", 0), ("ends", 1), ("axes", 0)):
        init = onnx.numpy_helper.from_array(np.array([value], np.int64), f"{out_name}_{suffix}")
        graph.initializer.append(init)
        bounds.append(init.name)
    return onnx.helper.make_node("Slice", [name] + bounds, [out_name], name=out_name)


def _toposort(graph) -> None:
    """Order ``graph.node`` so every node follows the producers of its inputs (stable otherwise)."""
    ready = {i.name for i in graph.input} | {t.name for t in graph.initializer} | {""}
    pending = list(graph.node)
    ordered = []
    while pending:
        rest = []
        for node in pending:
            if all(i in ready for i in node.input):
                ordered.append(node)
                ready.update(node.output)
            else:
                rest.append(node)
        if len(rest) == len(pending):
            raise ValueError(f"graph has a cycle or an undefined input at node {rest[0].name!r}")
        pending = rest
    del graph.node[:]
    graph.node.extend(ordered)


def _prune_to_outputs(graph) -> None:
    """Drop the nodes, initializers and value_info no graph output needs."""
    needed = {o.name for o in graph.output}
    kept = []
    for node in reversed(graph.node):
        if any(o in needed for o in node.output):
            kept.append(node)
            needed.update(i for i in node.input if i)
    kept.reverse()
    del graph.node[:]
    graph.node.extend(kept)
    for field in (graph.initializer, graph.value_info):
        survivors = [v for v in field if v.name in needed]
        del field[:]
        field.extend(survivors)


def outputs_identical(
    original: Callable[[dict], list[np.ndarray]],
    rewritten: Callable[[dict], list[np.ndarray]],
    feeds: Iterable[dict],
) -> bool:
    """Whether two runners give bit-identical outputs (same shapes, dtypes and bytes; NaNs equal
    where their bit patterns are) on every feed dict of ``feeds``; an exception from the rewritten
    runner counts as a difference."""
    for feed in feeds:
        want = original(feed)
        try:
            got = rewritten(feed)
        except Exception:  # noqa: BLE001 - onnxruntime raises several unrelated types
            return False
        for a, b in zip(want, got, strict=True):
            a, b = np.asarray(a), np.asarray(b)
            if a.shape != b.shape or a.dtype != b.dtype or a.tobytes() != b.tobytes():
                return False
    return True
