"""The images and links of an HTML page, for tests that check a report references only real files."""

from html.parser import HTMLParser


class PageLinks(HTMLParser):
    """``images``: every ``<img src>``; ``links``: every ``<a href>``, in page order."""

    def __init__(self, text: str = ""):
        super().__init__()
        self.images, self.links = [], []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs.get("src"))
        if tag == "a":
            self.links.append(attrs.get("href"))
