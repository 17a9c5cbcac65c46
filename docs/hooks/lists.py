"""MkDocs hook: a list may start right after a paragraph line, as it does on GitHub and in most
Markdown readers; Python-Markdown needs a blank line first and would otherwise run the items into
the paragraph. The page's text is unchanged; fenced code is left alone."""

import re

_ITEM = re.compile(r"^ {0,3}(?:[-*+]|\d+\.) ")
_FENCE = re.compile(r"^\s*(?:```|~~~)")


def breakless_lists(markdown: str) -> str:
    out: list[str] = []
    fenced = in_list = False
    for line in markdown.split("\n"):
        if _FENCE.match(line):
            fenced = not fenced
        elif not fenced:
            if _ITEM.match(line):
                prev = out[-1] if out else ""
                if prev.strip() and not in_list and not prev.lstrip().startswith(("|", "#")):
                    out.append("")
                in_list = True
            elif not line.strip():
                in_list = False
        out.append(line)
    return "\n".join(out)


def on_page_markdown(markdown, **kwargs):
    return breakless_lists(markdown)
