"""``generate``: one image in, one complete scene out (``run_generate``; the chain is ``chain.run_chain``)."""

from .chain import GenerateRequest, GenerateResult, fill_under_objects, report_waiter, run_chain, run_generate

__all__ = ["GenerateRequest", "GenerateResult", "fill_under_objects", "report_waiter", "run_chain", "run_generate"]
