"""PNG pictures of a map with paths on it (Pillow): map_server's colours, paths in the map frame."""
import numpy as np
from PIL import Image, ImageDraw

FREE, OCCUPIED, UNKNOWN = (254, 254, 254), (0, 0, 0), (205, 205, 205)
PATH_COLOURS = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (148, 103, 189), (255, 127, 14), (23, 190, 207)]


class MapPicture:
    """A map drawn `scale` pixels per cell, north up, with drawing helpers in map coordinates."""

    def __init__(self, data, resolution, origin, scale=4):
        data = np.asarray(data)
        self.height, self.width = data.shape
        self.resolution, self.origin, self.scale = resolution, origin, scale
        pixels = np.empty(data.shape + (3,), np.uint8)
        pixels[:] = UNKNOWN
        pixels[(data >= 0) & (data <= 25)] = FREE
        pixels[data >= 65] = OCCUPIED
        image = Image.fromarray(pixels[::-1], "RGB")  # row 0 is the lowest y: put it at the bottom
        self.image = image.resize((self.width * scale, self.height * scale), Image.NEAREST)
        self.draw = ImageDraw.Draw(self.image)

    def pixel(self, x, y):
        column = (x - self.origin[0]) / self.resolution * self.scale
        row = (self.height - (y - self.origin[1]) / self.resolution) * self.scale
        return float(column), float(row)

    def path(self, points, colour, width=3):
        points = [self.pixel(x, y) for x, y in np.asarray(points, float).reshape(-1, 2)]
        if len(points) > 1:
            self.draw.line(points, fill=colour, width=width, joint="curve")

    def marker(self, x, y, colour, radius=6, label=None):
        column, row = self.pixel(x, y)
        self.draw.ellipse([column - radius, row - radius, column + radius, row + radius], outline=colour, width=3)
        if label:
            self.draw.text((column + radius + 2, row - radius - 2), label, fill=colour)

    def legend(self, entries):
        """Lines of (colour, text) in the top-left corner."""
        width = max(self.text_width(text) for _, text in entries) + 28 if entries else 0
        self.draw.rectangle([2, 2, width, 6 + 14 * len(entries)], fill=(255, 255, 255), outline=(120, 120, 120))
        for index, (colour, text) in enumerate(entries):
            top = 4 + 14 * index
            self.draw.rectangle([4, top + 3, 16, top + 9], fill=colour)
            self.draw.text((20, top), text, fill=(0, 0, 0))

    def text_width(self, text):
        # Pillow 8+ has textlength; Ubuntu 20.04's Pillow 7 (CI's e2e job) only textsize.
        if hasattr(self.draw, "textlength"):
            return self.draw.textlength(text)
        return self.draw.textsize(text)[0]

    def save(self, path):
        self.image.save(str(path), format="PNG")
        return path
