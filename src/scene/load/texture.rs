//! Texture tables (`texture = { kind = ... }` in a material): which fields each kind
//! takes, and image files decoded once however many materials use them.

use super::*;

impl Ctx<'_> {
    pub(super) fn texture(&self, t: &TextureDesc) -> R<Texture> {
        let kind = t.kind.get_ref().as_str();
        // Fields each kind takes; any other one set is a mistake worth reporting.
        let allowed: &[&str] = match kind {
            "stripes" => &["colors", "axis", "width"],
            "checker" => &["colors", "size", "offset"],
            "image" => &["path", "scale", "offset", "color_space"],
            "planet" => &["seed", "resolution", "scale", "offset"],
            other => {
                return Err(self.err(
                    &t.kind,
                    "kind",
                    format!("unknown texture kind {other:?} (expected stripes, checker, image or planet)"),
                ));
            }
        };
        let present: [(&str, Option<usize>); 10] = [
            ("colors", t.colors.as_ref().map(|v| v.span().start)),
            ("axis", t.axis.as_ref().map(|v| v.span().start)),
            ("width", t.width.as_ref().map(|v| v.span().start)),
            ("size", t.size.as_ref().map(|v| v.span().start)),
            ("offset", t.offset.as_ref().map(|v| v.span().start)),
            ("scale", t.scale.as_ref().map(|v| v.span().start)),
            ("path", t.path.as_ref().map(|v| v.span().start)),
            ("seed", t.seed.as_ref().map(|v| v.span().start)),
            ("resolution", t.resolution.as_ref().map(|v| v.span().start)),
            ("color_space", t.color_space.as_ref().map(|v| v.span().start)),
        ];
        for (field, at) in present {
            if let Some(at) = at
                && !allowed.contains(&field)
            {
                return Err(self.error_at(at, field, format!("does not apply to a {kind} texture")));
            }
        }
        let required = |present: bool, field: &str| -> R<()> {
            if present { Ok(()) } else { Err(self.err(&t.kind, field, format!("a {kind} texture needs `{field}`"))) }
        };
        let colors = || -> R<[Color; 2]> {
            required(t.colors.is_some(), "colors")?;
            let c = t.colors.as_ref().expect("checked");
            let [a, b] = *c.get_ref();
            let check = |v: V3| {
                let v = Vec3::from_array(v);
                if v.is_finite() && v.min_element() >= 0.0 {
                    Ok(v)
                } else {
                    Err(self.err(c, "colors", "colours must be finite and >= 0"))
                }
            };
            Ok([check(a)?.into(), check(b)?.into()])
        };
        let vec2 = |v: &Option<S<Vec<f32>>>, field: &str, default: Vec2| -> R<Vec2> {
            match v {
                None => Ok(default),
                Some(s) => match s.get_ref().as_slice() {
                    [a, b] if a.is_finite() && b.is_finite() => Ok(Vec2::new(*a, *b)),
                    _ => Err(self.err(s, field, "must be two finite numbers [u, v]")),
                },
            }
        };
        match kind {
            "stripes" => {
                required(t.axis.is_some(), "axis")?;
                required(t.width.is_some(), "width")?;
                let axis = crate::math::unit_or(self.direction(t.axis.as_ref().expect("checked"), "axis")?, Vec3::Y);
                let width = self.positive(t.width.as_ref().expect("checked"), "width")?;
                Ok(Texture::Stripes { axis, width, colors: colors()? })
            }
            "checker" => {
                required(t.size.is_some(), "size")?;
                let size = self.positive(t.size.as_ref().expect("checked"), "size")?;
                let offset = match &t.offset {
                    None => Vec3::ZERO,
                    Some(s) => match s.get_ref().as_slice() {
                        [a, b, c] if [a, b, c].iter().all(|x| x.is_finite()) => Vec3::new(*a, *b, *c),
                        _ => return Err(self.err(s, "offset", "must be three finite numbers [x, y, z]")),
                    },
                };
                Ok(Texture::Checker { size, offset, colors: colors()? })
            }
            "image" => {
                required(t.path.is_some(), "path")?;
                let p = t.path.as_ref().expect("checked");
                let path = self.base_dir.join(p.get_ref());
                let encoding = match &t.color_space {
                    None => ColorEncoding::Linear,
                    Some(c) => ColorEncoding::parse(c.get_ref()).ok_or_else(|| {
                        self.err(c, "color_space", format!("expected \"linear\" or \"srgb\", got {:?}", c.get_ref()))
                    })?,
                };
                let map =
                    self.image(&path, encoding).map_err(|e| self.err(p, "path", format!("{}: {e}", path.display())))?;
                Ok(Texture::Image {
                    map,
                    scale: vec2(&t.scale, "scale", Vec2::ONE)?,
                    offset: vec2(&t.offset, "offset", Vec2::ZERO)?,
                })
            }
            _ => {
                let seed = t.seed.as_ref().map_or(Ok(1), |s| self.int_in(s, "seed", 0, u32::MAX as i64, ""))?;
                let [w, h] = match &t.resolution {
                    None => [1024, 512],
                    Some(r) => {
                        let [w, h] = *r.get_ref();
                        if !(1..=MAX_RESOLUTION).contains(&w) || !(1..=MAX_RESOLUTION).contains(&h) {
                            return Err(self.err(
                                r,
                                "resolution",
                                format!("sides must be between 1 and {MAX_RESOLUTION}"),
                            ));
                        }
                        let need = (w * h) as u64 * crate::texture::TEXEL_BYTES;
                        if need > crate::texture::MAX_TEXTURE_BYTES {
                            let message = format!(
                                "a {w}x{h} map needs about {:.1} GiB; the limit is {:.2} GiB (8192x8192)",
                                need as f64 / (1u64 << 30) as f64,
                                crate::texture::MAX_TEXTURE_BYTES as f64 / (1u64 << 30) as f64
                            );
                            return Err(self.err(r, "resolution", message));
                        }
                        [w as u32, h as u32]
                    }
                };
                Ok(Texture::Image {
                    map: Arc::new(planet(w, h, seed as u64)),
                    scale: vec2(&t.scale, "scale", Vec2::ONE)?,
                    offset: vec2(&t.offset, "offset", Vec2::ZERO)?,
                })
            }
        }
    }

    fn image(&self, path: &Path, encoding: ColorEncoding) -> Result<Arc<ImageMap>, crate::texture::TextureError> {
        let key = (path.to_owned(), encoding);
        if let Some(m) = self.images.borrow().get(&key) {
            return Ok(m.clone());
        }
        let map = Arc::new(ImageMap::load_as(path, encoding)?);
        self.images.borrow_mut().insert(key, map.clone());
        Ok(map)
    }
}
